#pragma once
// Row-parallel loops for the synthetic scene generator. Work is handed out in fixed chunks claimed dynamically, so
// callers must make the result for each index independent of the thread that computes it (they do: every pixel is
// a pure function of position and seed).
#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace seasonview::synth {

/// Calls fn(begin, end) for consecutive chunks of [0, count) of `chunk` indices on up to `threads` threads
/// (threads <= 1 runs inline). Returns when all chunks are done.
template <class Fn> void parallelChunks(int count, int chunk, int threads, const Fn& fn) {
    if (count <= 0) return;
    chunk = std::max(chunk, 1);
    const int chunks = (count + chunk - 1) / chunk;
    const int n = std::min(threads, chunks);
    if (n <= 1) {
        fn(0, count);
        return;
    }
    std::atomic<int> next{0};
    auto worker = [&] {
        for (int c = next.fetch_add(1); c < chunks; c = next.fetch_add(1)) fn(c * chunk, std::min(count, (c + 1) * chunk));
    };
    std::vector<std::thread> pool;
    pool.reserve(static_cast<size_t>(n - 1));
    for (int i = 1; i < n; ++i) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();
}

} // namespace seasonview::synth
