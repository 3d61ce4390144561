#include "HttpTestServer.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace seasonview::test {

namespace {

void sendAll(int fd, const char* data, size_t n) {
    while (n > 0) {
        const ssize_t w = ::send(fd, data, n, MSG_NOSIGNAL);
        if (w <= 0) return;
        data += w;
        n -= size_t(w);
    }
}

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

const char* reason(int status) {
    switch (status) {
    case 200: return "OK";
    case 206: return "Partial Content";
    case 404: return "Not Found";
    case 416: return "Range Not Satisfiable";
    case 429: return "Too Many Requests";
    case 500: return "Internal Server Error";
    case 503: return "Service Unavailable";
    default: return "Status";
    }
}

} // namespace

HttpTestServer::HttpTestServer(std::filesystem::path root) : m_root(std::move(root)) {
    // The seasonview processes the tests start reach this server directly, whatever proxy the machine names.
    for (const char* var : {"no_proxy", "NO_PROXY"}) ::setenv(var, "127.0.0.1,localhost", 1);
    m_listen = ::socket(AF_INET, SOCK_STREAM, 0);
    int one = 1;
    ::setsockopt(m_listen, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = 0;
    ::bind(m_listen, reinterpret_cast<sockaddr*>(&a), sizeof a);
    ::listen(m_listen, 64);
    socklen_t len = sizeof a;
    ::getsockname(m_listen, reinterpret_cast<sockaddr*>(&a), &len);
    m_port = ntohs(a.sin_port);
    m_thread = std::thread([this] { serve(); });
}

HttpTestServer::~HttpTestServer() { stop(); }

std::string HttpTestServer::url() const { return "http://127.0.0.1:" + std::to_string(m_port); }

void HttpTestServer::setFault(const std::string& path, Fault f) {
    std::lock_guard lock(m_mutex);
    m_faults[path] = f;
}

void HttpTestServer::clearFaults() {
    std::lock_guard lock(m_mutex);
    m_faults.clear();
}

std::vector<HttpTestServer::Request> HttpTestServer::requests() const {
    std::lock_guard lock(m_mutex);
    return m_requests;
}

void HttpTestServer::clearRequests() {
    std::lock_guard lock(m_mutex);
    m_requests.clear();
    m_maxActive = 0;
}

void HttpTestServer::stop() {
    if (m_stop.exchange(true)) return;
    // No connection is accepted from now on (a client's connect is refused), and requests in flight are cut.
    if (m_listen >= 0) ::shutdown(m_listen, SHUT_RDWR);
    if (m_thread.joinable()) m_thread.join();
    for (std::thread& t : m_workers) t.join();
    m_workers.clear();
    if (m_listen >= 0) ::close(m_listen);
    m_listen = -1;
}

void HttpTestServer::serve() {
    while (!m_stop) {
        pollfd p{m_listen, POLLIN, 0};
        if (::poll(&p, 1, 50) <= 0) continue;
        const int fd = ::accept(m_listen, nullptr, nullptr);
        if (fd < 0) continue;
        m_workers.emplace_back([this, fd] {
            const int now = ++m_active;
            for (int seen = m_maxActive; now > seen && !m_maxActive.compare_exchange_weak(seen, now);) {
            }
            bool answered = false;
            handle(fd, answered);
            ::close(fd);
            if (!answered) --m_active;
        });
    }
}

void HttpTestServer::handle(int fd, bool& answered) {
    // The request's head (bounded: 64 KiB, 5 s).
    std::string head;
    char buf[4096];
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (head.find("\r\n\r\n") == std::string::npos && head.size() < 65536 && std::chrono::steady_clock::now() < until) {
        pollfd p{fd, POLLIN, 0};
        if (::poll(&p, 1, 100) <= 0) continue;
        const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
        if (n <= 0) return;
        head.append(buf, size_t(n));
    }
    std::istringstream in(head);
    Request r;
    std::string version;
    in >> r.method >> r.path >> version;
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line) && line != "\r") {
        const auto colon = line.find(':');
        if (colon == std::string::npos) continue;
        const std::string name = lower(line.substr(0, colon));
        std::string value = line.substr(colon + 1);
        value.erase(0, value.find_first_not_of(' '));
        if (!value.empty() && value.back() == '\r') value.pop_back();
        if (name == "range") r.range = value;
        if (name == "user-agent") r.userAgent = value;
    }
    Fault f;
    r.at = std::chrono::steady_clock::now();
    {
        std::lock_guard lock(m_mutex);
        m_requests.push_back(r);
        auto it = m_faults.find(r.path);
        if (it == m_faults.end()) it = m_faults.find("*");
        if (it != m_faults.end() && it->second.times != 0) {
            f = it->second;
            if (it->second.times > 0) --it->second.times;
        }
    }
    if (f.latencyMs > 0) std::this_thread::sleep_for(std::chrono::milliseconds(f.latencyMs));
    if (m_stop) return; // stopped while this request waited: cut without an answer
    if (f.reset) {
        linger l{1, 0}; // RST on close
        ::setsockopt(fd, SOL_SOCKET, SO_LINGER, &l, sizeof l);
        return;
    }
    const bool headOnly = r.method == "HEAD";
    auto answer = [&](int status, const std::string& type, const std::string& body, long long total,
                      const std::string& extra) {
        std::string h = "HTTP/1.1 " + std::to_string(status) + " " + reason(status) + "\r\nContent-Type: " + type +
                        "\r\nContent-Length: " + std::to_string(total) + "\r\nAccept-Ranges: bytes\r\n" +
                        "Last-Modified: Wed, 25 Nov 2026 10:00:00 GMT\r\n" + extra + "Connection: close\r\n\r\n";
        // No longer counted as open from here: the client may start its next request as soon as it has read this
        // answer, before this thread has closed the socket (a count until the close would see one too many).
        if (!answered) {
            answered = true;
            --m_active;
        }
        sendAll(fd, h.data(), h.size());
        if (!headOnly) {
            const size_t n = f.cutAt >= 0 ? std::min(body.size(), size_t(f.cutAt)) : body.size();
            sendAll(fd, body.data(), n);
        }
    };
    if (f.status) {
        const std::string body = "error " + std::to_string(f.status) + "\n";
        answer(f.status, "text/plain", body, (long long)body.size(),
               f.retryAfterS >= 0 ? "Retry-After: " + std::to_string(f.retryAfterS) + "\r\n" : std::string());
        return;
    }
    if (f.html) {
        const std::string body = "<!DOCTYPE html><html><body><h1>Service temporarily unavailable</h1></body></html>\n";
        answer(200, "text/html", body, (long long)body.size(), "");
        return;
    }
    const std::string local = r.path.substr(0, r.path.find('?')); // a query string names the same file
    const size_t name = local.find_first_not_of('/');
    const std::filesystem::path file = name == std::string::npos ? m_root : m_root / local.substr(name);
    std::error_code ec;
    if (r.path.find("..") != std::string::npos || !std::filesystem::is_regular_file(file, ec)) {
        answer(404, "text/plain", "not found\n", 10, "");
        return;
    }
    std::ifstream s(file, std::ios::binary);
    const std::string data((std::istreambuf_iterator<char>(s)), std::istreambuf_iterator<char>());
    const long long size = (long long)data.size();
    if (r.range.rfind("bytes=", 0) == 0 && r.range.find(',') == std::string::npos) {
        const std::string spec = r.range.substr(6);
        const auto dash = spec.find('-');
        long long a = std::atoll(spec.substr(0, dash).c_str());
        long long b = dash + 1 < spec.size() ? std::atoll(spec.substr(dash + 1).c_str()) : size - 1;
        b = std::min(b, size - 1);
        if (a > b || a >= size) {
            answer(416, "text/plain", "", 0, "Content-Range: bytes */" + std::to_string(size) + "\r\n");
            return;
        }
        answer(206, "application/octet-stream", data.substr(size_t(a), size_t(b - a + 1)), b - a + 1,
               "Content-Range: bytes " + std::to_string(a) + "-" + std::to_string(b) + "/" + std::to_string(size) +
                   "\r\n");
        return;
    }
    answer(200, "application/octet-stream", data, size, "");
}

} // namespace seasonview::test
