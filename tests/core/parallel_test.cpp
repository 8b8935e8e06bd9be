#include "core/parallel.h"

#include <atomic>
#include <chrono>
#include <cstddef>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace strata {
namespace {

// Every item of every nested call runs exactly once, each writing its own slot: the slots hold
// what a plain double loop computes, for any thread count.
TEST(ParallelFor, NestedCallsRunEveryItemOnce) {
    constexpr std::size_t outer = 7;
    constexpr std::size_t inner = 23;
    for (const unsigned threads : {1u, 2u, 3u}) {
        SCOPED_TRACE(threads);
        std::vector<std::atomic<int>> runs(outer * inner);
        std::vector<std::size_t> value(outer * inner, 0);
        parallel_for(outer, threads, [&](std::size_t i) {
            parallel_for(inner, threads, [&](std::size_t j) {
                ++runs[i * inner + j];
                value[i * inner + j] = i * 1000 + j;
            });
        });
        for (std::size_t i = 0; i < outer; ++i) {
            for (std::size_t j = 0; j < inner; ++j) {
                EXPECT_EQ(runs[i * inner + j].load(), 1);
                EXPECT_EQ(value[i * inner + j], i * 1000 + j);
            }
        }
    }
}

// One long outer item and a short one on 2 threads: the thread done with the short item takes
// the long item's inner items. The long item's first inner item waits (at most 60 s) until
// another thread has run an inner item; without the help it waits for nothing.
TEST(ParallelFor, IdleThreadsHelpWithALongItemsInnerItems) {
    std::atomic<bool> helped{false};
    parallel_for(2, 2, [&](std::size_t i) {
        if (i != 0) {
            return;
        }
        const std::thread::id owner = std::this_thread::get_id();
        parallel_for(2, 2, [&](std::size_t) {
            if (std::this_thread::get_id() != owner) {
                helped = true;
                return;
            }
            const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
            while (!helped && std::chrono::steady_clock::now() < give_up) {
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            }
        });
    });
    EXPECT_TRUE(helped);
}

// An exception in an inner item reaches the inner call's caller, and through the outer call
// its caller; the other items still finish or are not started.
TEST(ParallelFor, InnerExceptionReachesTheCaller) {
    for (const unsigned threads : {1u, 2u, 3u}) {
        SCOPED_TRACE(threads);
        std::atomic<int> caught{0};
        EXPECT_THROW(parallel_for(4, threads,
                                  [&](std::size_t i) {
                                      try {
                                          parallel_for(10, threads, [&](std::size_t j) {
                                              if (i == 1 && j == 5) {
                                                  throw std::runtime_error("inner");
                                              }
                                          });
                                      } catch (const std::runtime_error&) {
                                          ++caught;
                                          throw;
                                      }
                                  }),
                     std::runtime_error);
        EXPECT_EQ(caught.load(), 1);
    }
}

}  // namespace
}  // namespace strata
