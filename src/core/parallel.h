#pragma once

#include <algorithm>
#include <condition_variable>
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

namespace detail {

/// The items of one parallel_for call, claimed one at a time by the threads of a pool.
struct ParallelJob {
    std::size_t count = 0;
    std::size_t next = 0;    ///< the next item to claim; count when all are claimed
    std::size_t active = 0;  ///< claimed items not finished yet
    void (*call)(const void* body, std::size_t i) = nullptr;
    const void* body = nullptr;
    std::exception_ptr error;  ///< the first exception a body threw (then no item is claimed)
};

/// The threads of the outermost parallel_for and the jobs they take items from: the outermost
/// call's, and those of parallel_for calls made inside its items, so that a thread with nothing
/// left of the outer job helps with the inner work of the items still running (one large label's
/// slabs, while the other labels are done).
struct ParallelPool {
    std::mutex mutex;
    std::condition_variable changed;
    std::vector<ParallelJob*> jobs;  ///< jobs with items left to claim, oldest first
};

/// The pool whose items this thread runs, or null outside every parallel_for.
inline thread_local ParallelPool* current_pool = nullptr;

/// Claims and runs items of the pool's jobs until `job` is finished: its items are all claimed
/// and none is running. With `only_own`, takes items of `job` only (a nested call waits for its
/// own items without starting another job's long item). `lock` holds the pool's mutex.
inline void run_until_finished(ParallelPool& pool,
                               ParallelJob& job,
                               bool only_own,
                               std::unique_lock<std::mutex>& lock) {
    for (;;) {
        ParallelJob* take = nullptr;
        if (job.next < job.count) {
            take = &job;
        } else if (!only_own && !pool.jobs.empty()) {
            take = pool.jobs.front();
        }
        if (take == nullptr) {
            if (job.active == 0) {
                return;
            }
            pool.changed.wait(lock);
            continue;
        }
        const std::size_t i = take->next++;
        if (take->next == take->count) {
            pool.jobs.erase(std::find(pool.jobs.begin(), pool.jobs.end(), take));
        }
        ++take->active;
        lock.unlock();
        std::exception_ptr error;
        try {
            take->call(take->body, i);
        } catch (...) {
            error = std::current_exception();
        }
        lock.lock();
        if (error && !take->error) {
            take->error = error;
            if (take->next < take->count) {
                take->next = take->count;
                pool.jobs.erase(std::find(pool.jobs.begin(), pool.jobs.end(), take));
            }
        }
        if (--take->active == 0 && take->next == take->count) {
            pool.changed.notify_all();
        }
    }
}

}  // namespace detail

/// Runs body(i) for i in [0, count) on up to `threads` threads (0: all cores). Items are
/// independent; results must be written to per-item slots so output is identical for any thread
/// count. The first exception thrown by a body is rethrown after all threads stopped.
///
/// Called inside an item of another parallel_for (threads > 1), it runs on that call's threads:
/// its items are offered to them, and a thread that has finished its share of the outer items
/// takes them. Order and results are those of a plain loop either way.
template <class Body>
void parallel_for(std::size_t count, unsigned threads, const Body& body) {
    const unsigned n = std::min<std::size_t>(resolve_thread_count(threads), count);
    if (n <= 1) {
        for (std::size_t i = 0; i < count; ++i) {
            body(i);
        }
        return;
    }
    detail::ParallelJob job;
    job.count = count;
    job.body = &body;
    job.call = [](const void* b, std::size_t i) { (*static_cast<const Body*>(b))(i); };
    if (detail::ParallelPool* pool = detail::current_pool) {
        std::unique_lock<std::mutex> lock(pool->mutex);
        pool->jobs.push_back(&job);
        pool->changed.notify_all();
        detail::run_until_finished(*pool, job, true, lock);
        lock.unlock();
        if (job.error) {
            std::rethrow_exception(job.error);
        }
        return;
    }
    detail::ParallelPool pool;
    pool.jobs.push_back(&job);
    auto worker = [&pool, &job] {
        detail::current_pool = &pool;
        std::unique_lock<std::mutex> lock(pool.mutex);
        detail::run_until_finished(pool, job, false, lock);
        lock.unlock();
        detail::current_pool = nullptr;
    };
    std::vector<std::thread> workers;
    workers.reserve(n - 1);
    for (unsigned t = 1; t < n; ++t) {
        workers.emplace_back(worker);
    }
    worker();
    for (std::thread& t : workers) {
        t.join();
    }
    if (job.error) {
        std::rethrow_exception(job.error);
    }
}

}  // namespace strata
