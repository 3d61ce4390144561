#include "WebSource.h"

#include "AtomicFile.h"
#include "GdalSupport.h"
#include "StableHash.h"

#include <cpl_conv.h>
#include <cpl_http.h>
#include <cpl_minixml.h>
#include <cpl_string.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>
#include <vector>

// GDAL's MD5 of a text as 32 hex digits (exported by libgdal, not in its installed headers): the name its WMS file
// cache gives a tile (cachedTileBytes).
extern "C" const char* CPLMD5String(const char* text);

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

/// One request through GDAL's HTTP client (seasonview's User-Agent, GDAL's timeout and retries): the status (200, or
/// the 400+ GDAL reports as "HTTP error code : N"), content type, headers and body; an error naming the URL when no
/// answer came.
struct Answer {
    std::string status = "200";
    std::string contentType;
    std::string contentLength, lastModified, etag, retryAfter;
    std::vector<std::uint8_t> body;
};

/// One request, no retry.
Result<Answer> fetchOnce(const std::string& url, bool headOnly) {
    gdal::init();
    gdal::ErrorCapture quiet;
    const std::string agent = "USERAGENT=" + userAgent();
    std::vector<const char*> options = {agent.c_str(), "TIMEOUT=30", "MAX_RETRY=0"};
    if (headOnly) options.insert(options.end(), {"CUSTOMREQUEST=HEAD", "NO_BODY=YES"});
    options.push_back(nullptr);
    CPLHTTPResult* r = CPLHTTPFetch(url.c_str(), options.data());
    if (!r) return fileError(url, "no answer (HTTP is not available in this GDAL)");
    struct Free {
        CPLHTTPResult* r;
        ~Free() { CPLHTTPDestroyResult(r); }
    } freeing{r};
    Answer a;
    a.retryAfter = header(r->papszHeaders, "retry-after");
    const std::string err = r->pszErrBuf ? r->pszErrBuf : "";
    if (const auto at = err.find("HTTP error code"); at != std::string::npos) {
        const auto digits = err.find_first_of("0123456789", at);
        a.status = digits == std::string::npos ? "?" : err.substr(digits, 3);
        return a;
    }
    if (r->nStatus != 0 || !err.empty())
        return fileError(url, "no answer from the server (" + (err.empty() ? "transfer failed" : err) + ")");
    a.contentType = lower(r->pszContentType ? r->pszContentType : "");
    a.contentLength = header(r->papszHeaders, "content-length");
    a.lastModified = header(r->papszHeaders, "last-modified");
    a.etag = header(r->papszHeaders, "etag");
    if (r->pabyData && r->nDataLen > 0) a.body.assign(r->pabyData, r->pabyData + r->nDataLen);
    return a;
}

/// 429, 502, 503, 504: a server (or its gateway) busy for now, worth asking again after a wait.
bool isBusy(const std::string& status) { return status == "429" || status == "502" || status == "503" || status == "504"; }

/// What a 429's or 503's Retry-After says, in seconds (at most 60); nothing when it names none (or a date).
std::optional<double> retryAfter(const Answer& a) {
    if ((a.status != "429" && a.status != "503") || a.retryAfter.empty() || a.retryAfter.size() >= 6 ||
        a.retryAfter.find_first_not_of("0123456789") != std::string::npos)
        return std::nullopt;
    return std::min(60.0, double(std::stoi(a.retryAfter)));
}

/// A request with retries (`retry`): up to 3 more on 429, 500 and 502-504 and on transfers that timed out or were
/// reset, after 1, 2 and 4 s, or after what the server's Retry-After says (seconds, at most 60) on 429 and 503.
Result<Answer> fetch(const std::string& url, bool headOnly, bool retry = true) {
    double delay = 1.0;
    for (int attempt = 1;; ++attempt) {
        auto a = fetchOnce(url, headOnly);
        bool again = false;
        double wait = delay;
        if (!a) {
            again = a.message().find("timed out") != std::string::npos || a.message().find("reset") != std::string::npos;
        } else {
            const std::string& st = a->status;
            again = st == "500" || isBusy(st);
            if (const auto named = retryAfter(*a)) wait = *named;
        }
        if (!retry || !again || attempt == 4) return a;
        std::this_thread::sleep_for(std::chrono::duration<double>(wait));
        delay *= 2.0;
    }
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
    // Asked once per process: the scene's opening and the pyramid's key ask for the same file.
    static std::mutex mutex;
    static std::map<std::string, std::string> known;
    {
        std::lock_guard lock(mutex);
        if (auto it = known.find(url); it != known.end()) return it->second;
    }
    auto a = fetch(url, true);
    if (!a) return a.error();
    if (a->status != "200") return fileError(url, "HTTP " + a->status + (a->status == "404" ? " (not found on the server)" : ""));
    if (a->contentType.rfind("text/html", 0) == 0)
        return fileError(url, "the server answers with a web page (text/html), not a raster");
    const std::string& size = a->contentLength;
    if (size.empty() || size.find_first_not_of("0123456789") != std::string::npos || size == "0")
        return fileError(url, "the server gives no size for it (a web raster is read by ranges: a file, e.g. a COG)");
    std::string id = url + "|" + size + "|" + a->lastModified + "|" + a->etag;
    std::lock_guard lock(mutex);
    known[url] = id;
    return id;
}

bool isTileTemplate(std::string_view s) {
    return isUrl(s) && s.find("{z}") != std::string_view::npos && s.find("{x}") != std::string_view::npos &&
           (s.find("{y}") != std::string_view::npos || s.find("{-y}") != std::string_view::npos);
}

namespace {

constexpr double kMercatorHalf = 20037508.342789244; // EPSG:3857's half extent
constexpr int kTileSize = 256;
constexpr int kMaxZoom = 22;

/// The template with {z}, {x} and {y} replaced.
std::string fillTemplate(std::string t, const std::string& z, const std::string& x, const std::string& y) {
    for (const auto& [key, v] : {std::pair<std::string, const std::string&>{"{z}", z}, {"{x}", x}, {"{y}", y}, {"{-y}", y}})
        for (size_t at = 0; (at = t.find(key, at)) != std::string::npos; at += v.size()) t.replace(at, key.size(), v);
    return t;
}

enum class Probe { Image, Missing };

/// GET of one tile: an image, missing (404, 204), or an error naming its URL. `retry`: as every request (GDAL's
/// retries with backoff on 5xx), else once (a diagnosis of a failure GDAL retried already).
Result<Probe> probeTile(const std::string& url, bool retry = true) {
    auto a = fetch(url, false, retry);
    if (!a) return a.error();
    if (a->status == "404") return Probe::Missing;
    if (a->status != "200") return fileError(url, "HTTP " + a->status);
    const std::vector<std::uint8_t>& d = a->body;
    if (d.empty()) return Probe::Missing; // 204
    const bool png = d.size() >= 8 && d[0] == 0x89 && d[1] == 'P' && d[2] == 'N' && d[3] == 'G';
    const bool jpeg = d.size() >= 3 && d[0] == 0xFF && d[1] == 0xD8 && d[2] == 0xFF;
    const bool webp = d.size() >= 12 && std::string_view(reinterpret_cast<const char*>(d.data()) + 8, 4) == "WEBP";
    if (!png && !jpeg && !webp)
        return fileError(url, "the server answers with " +
                                  (a->contentType.rfind("text/html", 0) == 0 ? std::string("a web page (text/html)")
                                                                             : "something else (" + a->contentType + ")") +
                                  ", not a PNG, JPEG or WebP tile");
    return Probe::Image;
}

std::string num(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.10f", v);
    return buf;
}

/// The name of a file in the cache derived from a text (StableHash.h, as the other caches name theirs).
std::string cacheName(const std::string& text) {
    char name[24];
    std::snprintf(name, sizeof name, "%016llx", static_cast<unsigned long long>(stableHash64(text)));
    return name;
}

std::string xmlEscape(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '&') o += "&amp;";
        else if (c == '<') o += "&lt;";
        else if (c == '>') o += "&gt;";
        else o += c;
    }
    return o;
}

} // namespace

namespace {

/// The elements of a service description that do not change its pixels (serviceIdentity).
constexpr const char* kRunElements[] = {"OfflineMode", "Cache", "MaxConnections", "Timeout", "UserAgent"};

/// `xml` without the elements named (each "<Name ...>...</Name>" or "<Name/>"), and without line breaks' spaces.
std::string withoutElements(std::string xml) {
    for (const std::string name : kRunElements) {
        for (size_t at = 0; (at = xml.find("<" + name, at)) != std::string::npos;) {
            const char next = at + 1 + name.size() < xml.size() ? xml[at + 1 + name.size()] : '\0';
            if (next != '>' && next != '/' && next != ' ') {
                at += name.size();
                continue;
            }
            const size_t open = xml.find('>', at);
            if (open == std::string::npos) break;
            size_t end = open + 1;
            if (xml[open - 1] != '/') {
                const size_t close = xml.find("</" + name + ">", open);
                if (close == std::string::npos) break;
                end = close + name.size() + 3;
            }
            xml.erase(at, end - at);
        }
    }
    std::string out;
    for (char c : xml)
        if (c != '\n' && c != '\r') out += c;
    return out;
}

/// Writes `text` to `file` unless it holds it already (so that an unchanged description keeps its date).
Result<Ok> writeIfChanged(const std::filesystem::path& file, const std::string& text) {
    if (std::ifstream in(file, std::ios::binary); in) {
        const std::string old((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        if (old == text) return Ok{};
    }
    std::string err;
    if (!writeTextAtomic(file, text, err)) return fileError(file.string(), err);
    return Ok{};
}

} // namespace

namespace {

/// Calls fn(path, modification time, bytes) for every file under a tile cache folder (none when it is missing).
template <typename Fn>
void forEachTile(const std::filesystem::path& dir, Fn&& fn) {
    std::error_code ec;
    for (std::filesystem::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        std::error_code e;
        if (!it->is_regular_file(e)) continue;
        const auto size = it->file_size(e);
        const auto time = it->last_write_time(e);
        if (!e) fn(it->path(), time, (long long)size);
    }
}

/// The GDAL <Cache> element of a service description over dir/tiles, that folder first bounded to options.cacheMb.
/// Tiles do not expire (10 years) and GDAL's cleaner is off (CleanTimeout 0): trimTileCache bounds the folder.
std::string tileCache(const std::filesystem::path& dir, const ServiceOptions& options);

} // namespace

long long trimTileCache(const std::filesystem::path& tilesDir, long long maxBytes) {
    struct Tile {
        std::filesystem::path path;
        std::filesystem::file_time_type time;
        long long bytes;
    };
    std::vector<Tile> tiles;
    long long total = 0;
    forEachTile(tilesDir, [&](const std::filesystem::path& p, std::filesystem::file_time_type time, long long bytes) {
        tiles.push_back({p, time, bytes});
        total += bytes;
    });
    if (total <= maxBytes) return 0;
    std::sort(tiles.begin(), tiles.end(), [](const Tile& a, const Tile& b) { return a.time < b.time; });
    long long removed = 0;
    std::error_code ec;
    for (const Tile& t : tiles) {
        if (total - removed <= maxBytes) break;
        if (std::filesystem::remove(t.path, ec)) removed += t.bytes;
    }
    return removed;
}

namespace {

std::string tileCache(const std::filesystem::path& dir, const ServiceOptions& options) {
    trimTileCache(dir / "tiles", (long long)(std::max(options.cacheMb, 0.0) * 1048576.0));
    return "<Cache><Path>" + xmlEscape((dir / "tiles").string()) +
           "</Path><Expires>315360000</Expires><CleanTimeout>0</CleanTimeout></Cache>";
}

} // namespace

bool isWmts(std::string_view input) {
    if (!isUrl(input) || isTileTemplate(input)) return false;
    const std::string l = lower(std::string(input));
    const auto q = l.find('?');
    if (q == std::string::npos || l.find("wmts") == std::string::npos) return false;
    std::istringstream params(l.substr(q + 1));
    for (std::string p; std::getline(params, p, '&');)
        if (p.rfind("layer=", 0) == 0 && p.size() > 6) return true;
    return false;
}

namespace {

std::string urlDecode(const std::string& s) {
    std::string o;
    for (size_t i = 0; i < s.size(); ++i) {
        if (s[i] == '%' && i + 2 < s.size() && std::isxdigit((unsigned char)s[i + 1]) &&
            std::isxdigit((unsigned char)s[i + 2])) {
            o += char(std::stoi(s.substr(i + 1, 2), nullptr, 16));
            i += 2;
        } else {
            o += s[i] == '+' ? ' ' : s[i];
        }
    }
    return o;
}

/// A WMTS input split: the capabilities document's URL (the other parameters kept) and the choices.
struct WmtsUrl {
    std::string capabilities, layer, tileMatrixSet, style;
};

WmtsUrl splitWmts(const std::string& url) {
    WmtsUrl w;
    const auto q = url.find('?');
    std::string kept;
    std::istringstream params(url.substr(q + 1));
    for (std::string p; std::getline(params, p, '&');) {
        const std::string key = lower(p.substr(0, p.find('=')));
        const std::string value = p.find('=') == std::string::npos ? "" : urlDecode(p.substr(p.find('=') + 1));
        if (key == "layer") w.layer = value;
        else if (key == "tilematrixset") w.tileMatrixSet = value;
        else if (key == "style") w.style = value;
        else if (!p.empty()) kept += (kept.empty() ? "" : "&") + p;
    }
    w.capabilities = url.substr(0, q) + (kept.empty() ? "" : "?" + kept);
    return w;
}

/// An XML document's nodes, freed with it.
struct Xml {
    CPLXMLNode* root = nullptr;
    explicit Xml(const std::string& text) : root(CPLParseXMLString(text.c_str())) {
        if (root) CPLStripXMLNamespace(root, nullptr, TRUE);
    }
    ~Xml() {
        if (root) CPLDestroyXMLNode(root);
    }
    Xml(const Xml&) = delete;
    Xml& operator=(const Xml&) = delete;
};

/// The element children of `parent` named `name`.
std::vector<CPLXMLNode*> children(CPLXMLNode* parent, const char* name) {
    std::vector<CPLXMLNode*> out;
    for (CPLXMLNode* c = parent ? parent->psChild : nullptr; c; c = c->psNext)
        if (c->eType == CXT_Element && std::string_view(c->pszValue) == name) out.push_back(c);
    return out;
}

std::string joined(const std::vector<std::string>& v) {
    std::string o;
    for (const auto& s : v) o += (o.empty() ? "" : ", ") + s;
    return o.empty() ? "none" : o;
}

CPLXMLNode* contentsOf(const Xml& x) { return x.root ? CPLGetXMLNode(x.root, "=Capabilities.Contents") : nullptr; }

} // namespace

Result<std::filesystem::path> describeWmts(const std::string& url,
                                           const std::function<Result<TileArea>(const Crs&)>& areaIn,
                                           const std::filesystem::path& cacheDir, const ServiceOptions& options) {
    gdal::init();
    const WmtsUrl w = splitWmts(url);
    const std::filesystem::path dir = cacheDir / "web";
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    // The capabilities, fetched once: a second run asks the server for nothing.
    const std::filesystem::path caps = dir / ("capabilities_" + cacheName(w.capabilities) + ".xml");
    if (!std::filesystem::exists(caps, ec)) {
        if (options.offline)
            return fileError(url, "not in the cache (--offline): no earlier run read this service's capabilities");
        auto a = fetch(w.capabilities, false);
        if (!a) return a.error();
        if (a->status != "200")
            return fileError(w.capabilities, "HTTP " + a->status + (a->status == "404" ? " (not found on the server)" : ""));
        if (a->contentType.rfind("text/html", 0) == 0)
            return fileError(w.capabilities, "the server answers with a web page (text/html), not WMTS capabilities");
        const std::string text(a->body.begin(), a->body.end());
        if (!contentsOf(Xml(text))) return fileError(w.capabilities, "not a WMTS capabilities document");
        std::string err;
        if (!writeTextAtomic(caps, text, err)) return fileError(caps.string(), err);
    }
    std::ifstream in(caps, std::ios::binary);
    const Xml doc(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()));
    CPLXMLNode* contents = contentsOf(doc);
    if (!contents) return fileError(caps.string(), "not a WMTS capabilities document");
    // The layer, its tile matrix set and style: as asked, else the first (the default style).
    CPLXMLNode* layer = nullptr;
    std::vector<std::string> names;
    for (CPLXMLNode* l : children(contents, "Layer")) {
        names.push_back(CPLGetXMLValue(l, "Identifier", ""));
        if (names.back() == w.layer) layer = l;
    }
    if (!layer) return fileError(url, "the service has no layer '" + w.layer + "' (it has: " + joined(names) + ")");
    std::vector<std::string> sets, styles;
    for (CPLXMLNode* l : children(layer, "TileMatrixSetLink")) sets.push_back(CPLGetXMLValue(l, "TileMatrixSet", ""));
    std::string style;
    for (CPLXMLNode* st : children(layer, "Style")) {
        styles.push_back(CPLGetXMLValue(st, "Identifier", ""));
        if (style.empty() && CPLTestBool(CPLGetXMLValue(st, "isDefault", "false"))) style = styles.back();
    }
    const std::string set = w.tileMatrixSet.empty() && !sets.empty() ? sets.front() : w.tileMatrixSet;
    if (std::find(sets.begin(), sets.end(), set) == sets.end())
        return fileError(url, "layer '" + w.layer + "' has no tile matrix set '" + set + "' (it has: " + joined(sets) + ")");
    if (!w.style.empty()) {
        if (std::find(styles.begin(), styles.end(), w.style) == styles.end())
            return fileError(url, "layer '" + w.layer + "' has no style '" + w.style + "' (it has: " + joined(styles) + ")");
        style = w.style;
    }
    if (style.empty() && !styles.empty()) style = styles.front();
    CPLXMLNode* matrixSet = nullptr;
    for (CPLXMLNode* t : children(contents, "TileMatrixSet"))
        if (std::string_view(CPLGetXMLValue(t, "Identifier", "")) == set) matrixSet = t;
    if (!matrixSet) return fileError(url, "the capabilities do not describe tile matrix set '" + set + "'");
    auto crs = Crs::fromUserInput(CPLGetXMLValue(matrixSet, "SupportedCRS", ""));
    if (!crs) return fileError(url, "tile matrix set '" + set + "': " + crs.message());
    auto area = areaIn(*crs);
    if (!area) return area.error();
    if (!(area->maxX > area->minX && area->maxY > area->minY && area->pixelSize > 0))
        return fileError(url, "no area to read the service over");
    // The tile matrix: the coarsest whose pixels (0.28 mm per pixel at its scale) are not larger than wanted.
    const double metresPerUnit = crs->isGeographic() ? 6378137.0 * 2.0 * 3.14159265358979323846 / 360.0 : 1.0;
    std::vector<std::pair<double, std::string>> matrices; // pixel size, identifier
    for (CPLXMLNode* m : children(matrixSet, "TileMatrix"))
        matrices.emplace_back(CPLAtof(CPLGetXMLValue(m, "ScaleDenominator", "0")) * 0.28e-3 / metresPerUnit,
                              CPLGetXMLValue(m, "Identifier", ""));
    std::sort(matrices.begin(), matrices.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    if (matrices.empty() || !(matrices.back().first > 0))
        return fileError(url, "tile matrix set '" + set + "' lists no tile matrix with a scale");
    auto chosen = matrices.back();
    for (const auto& m : matrices)
        if (m.first <= area->pixelSize * (1.0 + 1e-9)) {
            chosen = m;
            break;
        }
    const double w0 = (area->maxX - area->minX) / chosen.first, h0 = (area->maxY - area->minY) / chosen.first;
    if (w0 > gdal::kMaxRasterSide || h0 > gdal::kMaxRasterSide)
        return fileError(url, "the area is " + std::to_string((long long)w0) + "x" + std::to_string((long long)h0) +
                                  " pixels at tile matrix " + chosen.second + ", over the limit of " +
                                  std::to_string(gdal::kMaxRasterSide) + " a side (a smaller --extent)");
    const std::string cache = tileCache(dir, options);
    const std::string xml =
        "<GDAL_WMTS>\n  <GetCapabilitiesUrl>" + xmlEscape(caps.string()) + "</GetCapabilitiesUrl><Layer>" +
        xmlEscape(w.layer) + "</Layer><Style>" + xmlEscape(style) + "</Style><TileMatrixSet>" + xmlEscape(set) +
        "</TileMatrixSet><TileMatrix>" + xmlEscape(chosen.second) + "</TileMatrix>\n  <DataWindow><UpperLeftX>" +
        num(area->minX) + "</UpperLeftX><UpperLeftY>" + num(area->maxY) + "</UpperLeftY><LowerRightX>" +
        num(area->maxX) + "</LowerRightX><LowerRightY>" + num(area->minY) + "</LowerRightY></DataWindow>\n" +
        "  <BandsCount>4</BandsCount><ZeroBlockHttpCodes>204,404</ZeroBlockHttpCodes>\n"
        "  <MaxConnections>" + std::to_string(options.maxConnections) + "</MaxConnections><Timeout>30</Timeout><UserAgent>" + xmlEscape(userAgent()) +
        "</UserAgent><OfflineMode>" + (options.offline ? "true" : "false") + "</OfflineMode>\n  " + cache +
        "\n</GDAL_WMTS>\n";
    // Another connection bound (a streaming worker's) is another file: one description is never rewritten while
    // another reader has it open.
    const std::filesystem::path file =
        dir / (cacheName(withoutElements(xml) + (options.maxConnections == kDefaultConnections
                                                     ? std::string()
                                                     : "|connections " + std::to_string(options.maxConnections))) +
               ".xml");
    if (auto st = writeIfChanged(file, xml); !st) return st.error();
    return file;
}

namespace {

/// The text of element `name` in `xml` ("" when absent).
std::string elementText(const std::string& xml, const std::string& name) {
    const auto a = xml.find("<" + name + ">");
    if (a == std::string::npos) return {};
    const auto b = xml.find("</" + name + ">", a);
    return b == std::string::npos ? std::string() : xml.substr(a + name.size() + 2, b - a - name.size() - 2);
}

std::string readSmall(const std::filesystem::path& p) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(p, ec) || std::filesystem::file_size(p, ec) > (1u << 20)) return {};
    std::ifstream in(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::string xmlUnescape(std::string s) {
    for (const auto& [from, to] : {std::pair<std::string, std::string>{"&lt;", "<"}, {"&gt;", ">"}, {"&amp;", "&"}})
        for (size_t at = 0; (at = s.find(from, at)) != std::string::npos; at += to.size()) s.replace(at, from.size(), to);
    return s;
}

} // namespace

namespace {

/// The tiles a failed block of a WMTS description can be (its tile matrix and the three coarser), as URLs from the
/// layer's RESTful template; empty when the capabilities give none (a KVP-only service).
std::vector<std::string> wmtsTileCandidates(const std::string& xml, long long bx, long long by) {
    std::vector<std::string> urls;
    const Xml doc(readSmall(xmlUnescape(elementText(xml, "GetCapabilitiesUrl"))));
    CPLXMLNode* contents = contentsOf(doc);
    const std::string layerId = xmlUnescape(elementText(xml, "Layer")), style = xmlUnescape(elementText(xml, "Style"));
    const std::string setId = xmlUnescape(elementText(xml, "TileMatrixSet"));
    const std::string matrixId = xmlUnescape(elementText(xml, "TileMatrix"));
    const double minX = CPLAtof(elementText(xml, "UpperLeftX").c_str()), maxY = CPLAtof(elementText(xml, "UpperLeftY").c_str());
    std::string pattern;
    for (CPLXMLNode* l : children(contents, "Layer"))
        if (CPLGetXMLValue(l, "Identifier", "") == layerId)
            for (CPLXMLNode* r : children(l, "ResourceURL"))
                if (pattern.empty() && EQUAL(CPLGetXMLValue(r, "resourceType", ""), "tile"))
                    pattern = CPLGetXMLValue(r, "template", "");
    CPLXMLNode* set = nullptr;
    for (CPLXMLNode* t : children(contents, "TileMatrixSet"))
        if (CPLGetXMLValue(t, "Identifier", "") == setId) set = t;
    if (pattern.empty() || !set) return urls;
    const std::string crsName = CPLGetXMLValue(set, "SupportedCRS", "");
    auto crs = Crs::fromUserInput(crsName);
    if (!crs) return urls;
    const bool latFirst = crs->isGeographic() && crsName.find("CRS84") == std::string::npos; // EPSG:4326's axis order
    const double metresPerUnit = crs->isGeographic() ? 6378137.0 * 2.0 * 3.14159265358979323846 / 360.0 : 1.0;
    struct Matrix {
        double pixel, left, top;
        long long tileW, tileH, cols, rows;
        std::string id;
    };
    std::vector<Matrix> matrices;
    for (CPLXMLNode* m : children(set, "TileMatrix")) {
        double a = 0, b = 0;
        std::sscanf(CPLGetXMLValue(m, "TopLeftCorner", ""), "%lf %lf", &a, &b);
        matrices.push_back({CPLAtof(CPLGetXMLValue(m, "ScaleDenominator", "0")) * 0.28e-3 / metresPerUnit, latFirst ? b : a,
                            latFirst ? a : b, std::atoll(CPLGetXMLValue(m, "TileWidth", "256")),
                            std::atoll(CPLGetXMLValue(m, "TileHeight", "256")), std::atoll(CPLGetXMLValue(m, "MatrixWidth", "0")),
                            std::atoll(CPLGetXMLValue(m, "MatrixHeight", "0")), CPLGetXMLValue(m, "Identifier", "")});
    }
    std::sort(matrices.begin(), matrices.end(), [](const Matrix& a, const Matrix& b) { return a.pixel < b.pixel; });
    auto chosen = std::find_if(matrices.begin(), matrices.end(), [&](const Matrix& m) { return m.id == matrixId; });
    for (int k = 0; k <= 3 && chosen != matrices.end(); ++k, ++chosen) { // coarser: larger pixels
        const Matrix& m = *chosen;
        if (!(m.pixel > 0)) continue;
        const long long col = (long long)std::floor((minX - m.left) / (m.pixel * double(m.tileW)) + 1e-9) + bx;
        const long long row = (long long)std::floor((m.top - maxY) / (m.pixel * double(m.tileH)) + 1e-9) + by;
        if (col < 0 || row < 0 || (m.cols > 0 && col >= m.cols) || (m.rows > 0 && row >= m.rows)) continue;
        std::string url = pattern;
        for (const auto& [key, v] : {std::pair<std::string, std::string>{"{TileMatrix}", m.id},
                                     {"{TileCol}", std::to_string(col)},
                                     {"{TileRow}", std::to_string(row)},
                                     {"{Style}", style},
                                     {"{TileMatrixSet}", setId}})
            for (size_t p = 0; (p = url.find(key, p)) != std::string::npos; p += v.size()) url.replace(p, key.size(), v);
        urls.push_back(url);
    }
    return urls;
}

} // namespace

namespace {

/// A service description's GDAL_WMS or GDAL_WMTS XML (a TMS cut's VRT: the description it cuts), and where the
/// file's pixel (0, 0) is in the XML's blocks (a TMS cut starts at its area's first tile).
std::string describedXml(const std::filesystem::path& description, long long& blockX, long long& blockY) {
    std::string xml = readSmall(description);
    blockX = blockY = 0;
    if (xml.rfind("<VRTDataset", 0) == 0) { // a TMS description's cut: the first source is the description
        const auto a = xml.find("<SourceFilename relativeToVRT=\"0\">"), b = xml.find("</SourceFilename>");
        if (a == std::string::npos || b == std::string::npos || b < a) return {};
        long long xOff = 0, yOff = 0;
        if (const auto r = xml.find("<SrcRect xOff=\""); r != std::string::npos)
            std::sscanf(xml.c_str() + r, "<SrcRect xOff=\"%lld\" yOff=\"%lld\"", &xOff, &yOff);
        blockX = xOff / kTileSize, blockY = yOff / kTileSize;
        xml = readSmall(xmlUnescape(xml.substr(a + 34, b - a - 34)));
    }
    return xml;
}

/// The URLs of the tile of block (bx, by) of a description's XML, at its zoom and the `coarser` zooms above (GDAL may
/// have been reading an overview); a WMTS description's candidates.
std::vector<std::string> blockTileUrls(const std::string& xml, long long bx, long long by, int coarser) {
    if (xml.rfind("<GDAL_WMTS>", 0) == 0) return wmtsTileCandidates(xml, bx, by);
    if (xml.rfind("<GDAL_WMS>", 0) != 0) return {};
    const std::string server = xmlUnescape(elementText(xml, "ServerUrl"));
    const int z = std::atoi(elementText(xml, "TileLevel").c_str());
    const long long tx = std::atoll(elementText(xml, "TileX").c_str()), ty = std::atoll(elementText(xml, "TileY").c_str());
    const bool bottom = elementText(xml, "YOrigin") == "bottom";
    std::vector<std::string> urls;
    for (int k = 0; k <= coarser && k <= z; ++k) {
        const int zoom = z - k;
        const long long x = (tx >> k) + bx, row = (ty >> k) + by;
        if (x >= (1LL << zoom) || row >= (1LL << zoom)) continue;
        std::string tile = server;
        for (const auto& [key, v] : {std::pair<std::string, std::string>{"${z}", std::to_string(zoom)},
                                     {"${x}", std::to_string(x)},
                                     {"${y}", std::to_string(bottom ? (1LL << zoom) - 1 - row : row)}})
            for (size_t p = 0; (p = tile.find(key, p)) != std::string::npos; p += v.size()) tile.replace(p, key.size(), v);
        urls.push_back(tile);
    }
    return urls;
}

/// Asks the server again for the tile of block (bx, by) of a description's XML (blockTileUrls): the first that fails,
/// as one line naming its URL.
std::optional<Error> probeBlock(const std::string& xml, const std::filesystem::path& description, long long bx,
                                long long by, int coarser) {
    for (const std::string& tile : blockTileUrls(xml, bx, by, coarser))
        if (auto probe = probeTile(tile, false); !probe)
            return Error{probe.message() + " (reading " + description.string() + ")"};
    return std::nullopt;
}

/// GDAL's block numbers in "... Unable to download block X, Y ...".
std::optional<std::pair<long long, long long>> failedBlock(const std::string& message) {
    const auto at = message.find("download block ");
    if (at == std::string::npos) return std::nullopt;
    long long bx = -1, by = -1;
    if (std::sscanf(message.c_str() + at + 15, "%lld, %lld", &bx, &by) != 2 || bx < 0 || by < 0) return std::nullopt;
    return std::pair{bx, by};
}

} // namespace

std::optional<Error> tileFailure(const std::filesystem::path& description, const std::string& message) {
    long long ox = 0, oy = 0;
    const std::string xml = describedXml(description, ox, oy);
    const auto block = failedBlock(message);
    if (!block) return std::nullopt;
    return probeBlock(xml, description, block->first, block->second, 3); // GDAL's block numbers are the XML's own
}

std::optional<double> busyWait(const std::filesystem::path& description, const std::string& message, double fallback) {
    // GDAL's words ("HTTP status code: 429"), or as ErrorCapture shortens them ("(HTTP 429)").
    int code = 0;
    if (const auto at = message.find("HTTP status code: "); at != std::string::npos) code = std::atoi(message.c_str() + at + 18);
    else if (const auto at2 = message.find("(HTTP "); at2 != std::string::npos) code = std::atoi(message.c_str() + at2 + 6);
    if (!isBusy(std::to_string(code))) return std::nullopt;
    const auto block = failedBlock(message);
    long long ox = 0, oy = 0;
    const std::string xml = block ? describedXml(description, ox, oy) : std::string();
    if (xml.empty()) return fallback;
    // The block's tile (or the coarser ones GDAL may have been reading) asked once more: what it says now.
    for (const std::string& tile : blockTileUrls(xml, block->first, block->second, 3)) {
        auto a = fetchOnce(tile, false);
        if (!a) return fallback; // no answer: a transfer fault, the fallback's backoff
        const std::string& st = a->status;
        if (st == "200" || st == "404" || st == "204") continue;
        if (!isBusy(st)) return std::nullopt; // another status now (500, 403, ...): not worth another read
        return retryAfter(*a).value_or(fallback);
    }
    return 0.0; // answered now: read again at once
}

std::optional<Error> tileFailureIn(const std::filesystem::path& description, long long x0, long long y0, long long x1,
                                   long long y1) {
    long long ox = 0, oy = 0;
    const std::string xml = describedXml(description, ox, oy);
    if (xml.empty() || x1 <= x0 || y1 <= y0) return std::nullopt;
    int asked = 0;
    for (long long by = y0 / kTileSize; by * kTileSize < y1; ++by)
        for (long long bx = x0 / kTileSize; bx * kTileSize < x1; ++bx) {
            if (++asked > 64) return std::nullopt;
            if (auto e = probeBlock(xml, description, ox + bx, oy + by, 0)) return e;
        }
    return std::nullopt;
}

std::optional<long long> cachedTileBytes(const std::filesystem::path& description, long long col, long long row) {
    long long ox = 0, oy = 0;
    const std::string xml = describedXml(description, ox, oy);
    const auto cache = xml.find("<Cache>");
    if (xml.empty() || cache == std::string::npos) return std::nullopt;
    const std::filesystem::path dir = xmlUnescape(elementText(xml.substr(cache), "Path"));
    for (const std::string& url : blockTileUrls(xml, ox + col, oy + row, 0)) {
        // GDAL's file cache (3.6, depth 2): PATH/<the service's folder>/h0/h1/h, h the MD5 of the tile's URL.
        const std::string h = CPLMD5String(url.c_str());
        std::error_code ec;
        for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
            const std::filesystem::path f = it->path() / h.substr(0, 1) / h.substr(1, 1) / h;
            std::error_code e;
            const auto size = std::filesystem::file_size(f, e);
            if (!e) return (long long)size;
        }
    }
    return std::nullopt;
}

std::optional<long long> serviceTileCount(const std::filesystem::path& description) {
    const std::string text = readSmall(description);
    std::string w, h;
    if (text.rfind("<VRTDataset", 0) == 0) { // a TMS cut: its size
        const auto num = [&](const char* attr) {
            const auto at = text.find(attr);
            if (at == std::string::npos) return std::string();
            const auto from = at + std::strlen(attr), to = text.find('"', from);
            return to == std::string::npos ? std::string() : text.substr(from, to - from);
        };
        w = num("rasterXSize=\""), h = num("rasterYSize=\"");
        const auto a = text.find("<SourceFilename relativeToVRT=\"0\">"), b = text.find("</SourceFilename>");
        if (a == std::string::npos || b == std::string::npos || b < a ||
            readSmall(xmlUnescape(text.substr(a + 34, b - a - 34))).rfind("<GDAL_WMS>", 0) != 0)
            return std::nullopt;
    } else if (text.rfind("<GDAL_WMS>", 0) == 0) {
        w = elementText(text, "SizeX"), h = elementText(text, "SizeY");
    }
    const long long x = std::atoll(w.c_str()), y = std::atoll(h.c_str());
    if (x <= 0 || y <= 0) return std::nullopt;
    return ((x + kTileSize - 1) / kTileSize) * ((y + kTileSize - 1) / kTileSize);
}

TileFetchCounter::TileFetchCounter(std::filesystem::path tilesDir)
    : m_dir(std::move(tilesDir)), m_start(std::filesystem::file_time_type::clock::now()) {}

TileFetchCounter::Count TileFetchCounter::fetched() const {
    Count c;
    forEachTile(m_dir, [&](const std::filesystem::path&, std::filesystem::file_time_type time, long long bytes) {
        if (time < m_start) return;
        ++c.tiles;
        c.bytes += bytes;
    });
    return c;
}

std::optional<std::string> serviceIdentity(const std::filesystem::path& file) {
    std::error_code ec;
    if (lower(file.extension().string()) != ".xml" || !std::filesystem::is_regular_file(file, ec)) return std::nullopt;
    const auto size = std::filesystem::file_size(file, ec);
    if (ec || size > (1u << 20)) return std::nullopt;
    std::ifstream in(file, std::ios::binary);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (text.rfind("<GDAL_WMS>", 0) != 0 && text.rfind("<GDAL_WMTS>", 0) != 0) return std::nullopt;
    return "service|" + cacheName(withoutElements(text));
}

Result<std::filesystem::path> describeTileService(const std::string& url, const TileArea& area,
                                                  const std::filesystem::path& cacheDir,
                                                  const ServiceOptions& options) {
    gdal::init();
    const bool tms = url.find("{-y}") != std::string::npos; // rows counted from the bottom
    if (!(area.maxX > area.minX && area.maxY > area.minY && area.pixelSize > 0) || !std::isfinite(area.pixelSize))
        return fileError(url, "no area to read the tile service over");
    // The coarsest zoom whose pixels are not larger than wanted.
    int z = int(std::ceil(std::log2(2.0 * kMercatorHalf / kTileSize / area.pixelSize - 1e-9)));
    z = std::clamp(z, 0, kMaxZoom);
    const double cx = 0.5 * (area.minX + area.maxX), cy = 0.5 * (area.minY + area.maxY);
    // The zoom found is remembered in the cache, so that a second run asks the service for nothing.
    const std::filesystem::path dir = cacheDir / "web";
    const std::string probeKey = url + "|" + std::to_string(z) + "|" + num(cx) + "|" + num(cy);
    const std::filesystem::path memo = dir / ("zoom_" + cacheName(probeKey) + ".txt");
    std::error_code ec;
    bool known = false;
    if (std::ifstream in(memo); in) {
        int remembered = -1;
        if ((in >> remembered) && remembered >= 0 && remembered <= z) z = remembered, known = true;
    }
    if (!known && options.offline)
        return fileError(url, "not in the cache (--offline): no earlier run read this service over this area");
    for (; !known; --z) {
        const double t = 2.0 * kMercatorHalf / std::ldexp(1.0, z);
        const long long row = (long long)std::floor((kMercatorHalf - cy) / t);
        const auto probe = probeTile(fillTemplate(url, std::to_string(z),
                                                  std::to_string((long long)std::floor((cx + kMercatorHalf) / t)),
                                                  std::to_string(tms ? (1LL << z) - 1 - row : row)));
        if (!probe) return probe.error();
        if (*probe == Probe::Image) {
            std::filesystem::create_directories(dir, ec);
            std::string err;
            (void)writeTextAtomic(memo, std::to_string(z) + "\n", err); // not kept: the next run probes again
            break;
        }
        if (z == 0) return fileError(url, "the service has no tile over the area at any zoom (404)");
    }
    const long long n = 1LL << z;
    const double t = 2.0 * kMercatorHalf / double(n);
    const auto clampTile = [&](double v) { return std::clamp((long long)std::floor(v), 0LL, n - 1); };
    const long long x0 = clampTile((area.minX + kMercatorHalf) / t), x1 = clampTile((area.maxX + kMercatorHalf) / t - 1e-9);
    const long long y0 = clampTile((kMercatorHalf - area.maxY) / t), y1 = clampTile((kMercatorHalf - area.minY) / t - 1e-9);
    const long long w = (x1 - x0 + 1) * kTileSize, h = (y1 - y0 + 1) * kTileSize;
    if (w > gdal::kMaxRasterSide || h > gdal::kMaxRasterSide)
        return fileError(url, "the area is " + std::to_string(w) + "x" + std::to_string(h) + " pixels at zoom " +
                                  std::to_string(z) + ", over the limit of " + std::to_string(gdal::kMaxRasterSide) +
                                  " a side (a smaller --extent)");
    const std::string server = fillTemplate(url, "${z}", "${x}", "${y}"); // GDAL's TMS mini-driver's keys
    // XYZ: a window of the tiles the area touches (TileX/TileY: its first tile). TMS: GDAL numbers rows from the
    // window's bottom, so the window is the whole world and a VRT cuts the area from it.
    const std::string window =
        tms ? "<UpperLeftX>" + num(-kMercatorHalf) + "</UpperLeftX><UpperLeftY>" + num(kMercatorHalf) +
                  "</UpperLeftY><LowerRightX>" + num(kMercatorHalf) + "</LowerRightX><LowerRightY>" +
                  num(-kMercatorHalf) + "</LowerRightY><TileLevel>" + std::to_string(z) +
                  "</TileLevel><TileCountX>1</TileCountX><TileCountY>1</TileCountY><YOrigin>bottom</YOrigin>"
            : "<UpperLeftX>" + num(-kMercatorHalf + double(x0) * t) + "</UpperLeftX><UpperLeftY>" +
                  num(kMercatorHalf - double(y0) * t) + "</UpperLeftY><LowerRightX>" +
                  num(-kMercatorHalf + double(x1 + 1) * t) + "</LowerRightX><LowerRightY>" +
                  num(kMercatorHalf - double(y1 + 1) * t) + "</LowerRightY><SizeX>" + std::to_string(w) +
                  "</SizeX><SizeY>" + std::to_string(h) + "</SizeY><TileLevel>" + std::to_string(z) +
                  "</TileLevel><TileX>" + std::to_string(x0) + "</TileX><TileY>" + std::to_string(y0) +
                  "</TileY><YOrigin>top</YOrigin>";
    const std::string cache = tileCache(dir, options);
    const std::string xml =
        "<GDAL_WMS>\n  <Service name=\"TMS\"><ServerUrl>" + xmlEscape(server) + "</ServerUrl></Service>\n" +
        "  <DataWindow>" + window + "</DataWindow>\n" +
        "  <Projection>EPSG:3857</Projection><BlockSizeX>256</BlockSizeX><BlockSizeY>256</BlockSizeY>"
        "<BandsCount>4</BandsCount><ZeroBlockHttpCodes>204,404</ZeroBlockHttpCodes>\n"
        "  <MaxConnections>" + std::to_string(options.maxConnections) + "</MaxConnections><Timeout>30</Timeout><UserAgent>" + xmlEscape(userAgent()) +
        "</UserAgent><OfflineMode>" + (options.offline ? "true" : "false") + "</OfflineMode>\n  " + cache +
        "\n</GDAL_WMS>\n";
    std::filesystem::create_directories(dir, ec);
    // Named by what it describes (the run's options left out: serviceIdentity), rewritten when they change.
    // Another connection bound (a streaming worker's) is another file: one description is never rewritten while
    // another reader has it open.
    const std::filesystem::path file =
        dir / (cacheName(withoutElements(xml) + (options.maxConnections == kDefaultConnections
                                                     ? std::string()
                                                     : "|connections " + std::to_string(options.maxConnections))) +
               ".xml");
    if (auto st = writeIfChanged(file, xml); !st) return st.error();
    if (!tms) return file;
    const double px = t / kTileSize;
    std::string vrt = "<VRTDataset rasterXSize=\"" + std::to_string(w) + "\" rasterYSize=\"" + std::to_string(h) +
                      "\">\n  <SRS>EPSG:3857</SRS>\n  <GeoTransform>" + num(-kMercatorHalf + double(x0) * t) + ", " +
                      num(px) + ", 0, " + num(kMercatorHalf - double(y0) * t) + ", 0, " + num(-px) + "</GeoTransform>\n";
    const char* interp[4] = {"Red", "Green", "Blue", "Alpha"};
    for (int b = 1; b <= 4; ++b)
        vrt += "  <VRTRasterBand dataType=\"Byte\" band=\"" + std::to_string(b) +
               "\" blockXSize=\"256\" blockYSize=\"256\"><ColorInterp>" + interp[b - 1] +
               "</ColorInterp><SimpleSource><SourceFilename relativeToVRT=\"0\">" + xmlEscape(file.string()) +
               "</SourceFilename><SourceBand>" + std::to_string(b) + "</SourceBand><SrcRect xOff=\"" +
               std::to_string(x0 * kTileSize) + "\" yOff=\"" + std::to_string(y0 * kTileSize) + "\" xSize=\"" +
               std::to_string(w) + "\" ySize=\"" + std::to_string(h) + "\"/><DstRect xOff=\"0\" yOff=\"0\" xSize=\"" +
               std::to_string(w) + "\" ySize=\"" + std::to_string(h) + "\"/></SimpleSource></VRTRasterBand>\n";
    vrt += "</VRTDataset>\n";
    const std::filesystem::path cut = dir / (cacheName(vrt) + ".vrt");
    if (auto st = writeIfChanged(cut, vrt); !st) return st.error();
    return cut;
}

} // namespace seasonview::web
