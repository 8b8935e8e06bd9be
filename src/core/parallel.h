#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace strata {

/// Number of worker threads to use when an options struct says 0 ("all cores").
inline unsigned resolve_thread_count(unsigned requested) {
    if (requested != 0) {
        return requested;
    }
    return std::max(1u, std::thread::hardware_concurrency());
}

/// Runs body(i) for i in [0, count) on up to `threads` threads (0: all cores). Items are
/// independent; results must be written to per-item slots so output is identical for any thread
/// count. The first exception thrown by a body is rethrown after all threads stopped.
template <class Body>
void parallel_for(std::size_t count, unsigned threads, const Body& body) {
    const unsigned n = std::min<std::size_t>(resolve_thread_count(threads), count);
    if (n <= 1) {
        for (std::size_t i = 0; i < count; ++i) {
            body(i);
        }
        return;
    }
    std::atomic<std::size_t> next{0};
    std::exception_ptr error;
    std::mutex error_mutex;
    auto worker = [&] {
        for (;;) {
            const std::size_t i = next.fetch_add(1);
            if (i >= count) {
                return;
            }
            try {
                body(i);
            } catch (...) {
                std::lock_guard<std::mutex> lock(error_mutex);
                if (!error) {
                    error = std::current_exception();
                }
                next.store(count);
            }
        }
    };
    std::vector<std::thread> pool;
    pool.reserve(n - 1);
    for (unsigned t = 1; t < n; ++t) {
        pool.emplace_back(worker);
    }
    worker();
    for (std::thread& t : pool) {
        t.join();
    }
    if (error) {
        std::rethrow_exception(error);
    }
}

}  // namespace strata
