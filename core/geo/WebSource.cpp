#include "WebSource.h"

#include "GdalSupport.h"

#include <cpl_conv.h>
#include <cpl_http.h>
#include <cpl_string.h>

#include <algorithm>
#include <cctype>

#ifndef SEASONVIEW_VERSION
#define SEASONVIEW_VERSION "0"
#endif

namespace seasonview::web {

namespace {
constexpr std::string_view kCurl = "/vsicurl/";

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

/// A header's value from GDAL's list of "Name: value" (or "Name=value") lines; empty when absent.
std::string header(char** headers, const std::string& name) {
    for (char** h = headers; h && *h; ++h) {
        const std::string line = *h;
        const auto sep = line.find_first_of(":=");
        if (sep == std::string::npos || lower(line.substr(0, sep)) != name) continue;
        std::string v = line.substr(sep + 1);
        v.erase(0, v.find_first_not_of(' '));
        while (!v.empty() && (v.back() == '\r' || v.back() == '\n' || v.back() == ' ')) v.pop_back();
        return v;
    }
    return {};
}
} // namespace

bool isUrl(std::string_view s) {
    const std::string head = lower(std::string(s.substr(0, 8)));
    return head.rfind("http://", 0) == 0 || head.rfind("https://", 0) == 0;
}

std::filesystem::path gdalPath(const std::string& url) { return std::string(kCurl) + url; }

bool isRemote(const std::filesystem::path& p) { return p.native().rfind(kCurl, 0) == 0; }

std::string urlOf(const std::filesystem::path& p) { return isRemote(p) ? p.native().substr(kCurl.size()) : p.string(); }

RemoteOpen::RemoteOpen(const std::filesystem::path& path) : m_set(isRemote(path)) {
    if (!m_set) return;
    const char* previous = CPLGetThreadLocalConfigOption("GDAL_DISABLE_READDIR_ON_OPEN", nullptr);
    m_hadPrevious = previous != nullptr;
    if (previous) m_previous = previous;
    CPLSetThreadLocalConfigOption("GDAL_DISABLE_READDIR_ON_OPEN", "EMPTY_DIR");
}

RemoteOpen::~RemoteOpen() {
    if (m_set)
        CPLSetThreadLocalConfigOption("GDAL_DISABLE_READDIR_ON_OPEN", m_hadPrevious ? m_previous.c_str() : nullptr);
}

std::string userAgent() { return std::string("seasonview/") + SEASONVIEW_VERSION; }

Result<std::string> identity(const std::string& url) {
    gdal::init();
    gdal::ErrorCapture quiet;
    const std::string agent = "USERAGENT=" + userAgent();
    const char* options[] = {"CUSTOMREQUEST=HEAD", "NO_BODY=YES", agent.c_str(), nullptr};
    CPLHTTPResult* r = CPLHTTPFetch(url.c_str(), options);
    if (!r) return fileError(url, "no answer (HTTP is not available in this GDAL)");
    struct Free {
        CPLHTTPResult* r;
        ~Free() { CPLHTTPDestroyResult(r); }
    } freeing{r};
    const std::string err = r->pszErrBuf ? r->pszErrBuf : "";
    // GDAL says "HTTP error code : N" for a status of 400 or more.
    if (const auto at = err.find("HTTP error code"); at != std::string::npos) {
        const auto digits = err.find_first_of("0123456789", at);
        const std::string code = digits == std::string::npos ? "?" : err.substr(digits, 3);
        return fileError(url, "HTTP " + code + (code == "404" ? " (not found on the server)" : ""));
    }
    if (r->nStatus != 0 || !err.empty())
        return fileError(url, "no answer from the server (" + (err.empty() ? "transfer failed" : err) + ")");
    const std::string type = lower(r->pszContentType ? r->pszContentType : "");
    if (type.rfind("text/html", 0) == 0)
        return fileError(url, "the server answers with a web page (text/html), not a raster");
    const std::string size = header(r->papszHeaders, "content-length");
    if (size.empty() || size.find_first_not_of("0123456789") != std::string::npos || size == "0")
        return fileError(url, "the server gives no size for it (a web raster is read by ranges: a file, e.g. a COG)");
    return url + "|" + size + "|" + header(r->papszHeaders, "last-modified") + "|" + header(r->papszHeaders, "etag");
}

} // namespace seasonview::web
