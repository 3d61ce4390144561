#pragma once
// A small HTTP/1.1 file server on 127.0.0.1 for the web-input tests: HEAD and GET with single byte ranges (what
// GDAL's /vsicurl/ sends), one request per connection, and faults injected per path: a status, latency, an HTML
// page instead of the file, a body cut short, a connection reset. It logs every request. Started by the
// constructor on a free port, stopped by stop() (connections refused from then on, requests in flight cut without
// an answer: a server that stops mid-flight) or the destructor.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace seasonview::test {

class HttpTestServer {
public:
    struct Fault {
        int status = 0;          // answer this status (no body but a short text) instead of the file
        int latencyMs = 0;       // wait before answering
        bool html = false;       // 200 with an HTML error page instead of the file
        long long cutAt = -1;    // send only this many bytes of the body (Content-Length says the whole)
        bool reset = false;      // close the connection without answering
        int retryAfterS = -1;    // with `status`: a Retry-After header of this many seconds
        int times = -1;          // the fault applies to this many requests, then the file is served (-1: always)
    };
    struct Request {
        std::string method, path, range, userAgent;
        std::chrono::steady_clock::time_point at; // when its head arrived
    };

    explicit HttpTestServer(std::filesystem::path root);
    ~HttpTestServer();
    HttpTestServer(const HttpTestServer&) = delete;
    HttpTestServer& operator=(const HttpTestServer&) = delete;

    /// "http://127.0.0.1:PORT"
    std::string url() const;
    /// A fault for one path ("/leafon.tif"), or for every path ("*").
    void setFault(const std::string& path, Fault f);
    void clearFaults();
    std::vector<Request> requests() const;
    /// The most connections open at once since the start or clearRequests() (one request per connection), each counted
    /// from its accept to the start of its answer.
    int maxConcurrent() const { return m_maxActive; }
    void clearRequests();
    void stop();

private:
    void serve();
    void handle(int fd, bool& answered); // answered: no longer counted in maxConcurrent()

    std::filesystem::path m_root;
    int m_listen = -1;
    int m_port = 0;
    std::atomic<bool> m_stop{false};
    std::atomic<int> m_active{0}, m_maxActive{0};
    mutable std::mutex m_mutex;
    std::map<std::string, Fault> m_faults;
    std::vector<Request> m_requests;
    std::vector<std::thread> m_workers;
    std::thread m_thread;
};

} // namespace seasonview::test
