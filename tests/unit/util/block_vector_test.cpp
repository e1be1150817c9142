// BlockVector (core/util/block_vector.h): indexing across blocks, elements that never move
// while the sequence grows, clear() that destroys every element and keeps the blocks, and the
// random-access iterator.

#include "core/util/block_vector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <numeric>
#include <vector>

namespace render {
namespace {

// Small blocks (8 elements) so that a few dozen elements span several blocks.
using Small = BlockVector<int, 3>;

TEST(BlockVector, IndexesAcrossBlocksInInsertionOrder) {
    Small v;
    EXPECT_TRUE(v.empty());
    for (int i = 0; i < 100; ++i) v.push_back(i * 3);
    ASSERT_EQ(v.size(), 100u);
    EXPECT_EQ(v.block_count(), 13u);  // ceil(100 / 8)
    for (int i = 0; i < 100; ++i) ASSERT_EQ(v[i], i * 3) << i;
    v[42] = -1;
    EXPECT_EQ(std::as_const(v)[42], -1);
}

TEST(BlockVector, ElementsNeverMoveWhileTheSequenceGrows) {
    Small v;
    std::vector<const int*> addresses;
    for (int i = 0; i < 200; ++i) addresses.push_back(&v.emplace_back(i));
    for (int i = 0; i < 200; ++i) ASSERT_EQ(&v[i], addresses[i]) << i;
}

TEST(BlockVector, ClearDestroysEveryElementAndKeepsTheBlocks) {
    BlockVector<std::shared_ptr<int>, 3> v;
    auto counted = std::make_shared<int>(7);
    for (int i = 0; i < 50; ++i) v.push_back(counted);
    EXPECT_EQ(counted.use_count(), 51);
    const size_t blocks = v.block_count();
    // Blocks cleared one by one (as callers do in parallel), then clear().
    for (size_t b = 0; b < 3; ++b) v.clear_block(b);
    EXPECT_EQ(counted.use_count(), 51 - 24);
    v.clear();
    EXPECT_EQ(counted.use_count(), 1);
    EXPECT_TRUE(v.empty());
    EXPECT_EQ(v.block_count(), blocks);
    // Refilled: the kept blocks are used again, none added.
    for (int i = 0; i < 50; ++i) v.push_back(counted);
    EXPECT_EQ(v.block_count(), blocks);
    EXPECT_EQ(*v[49], 7);
}

TEST(BlockVector, IteratesInOrderWithRandomAccess) {
    Small v;
    for (int i = 0; i < 30; ++i) v.push_back(30 - i);
    std::vector<int> seen;
    for (int x : v) seen.push_back(x);
    ASSERT_EQ(seen.size(), 30u);
    for (int i = 0; i < 30; ++i) EXPECT_EQ(seen[i], 30 - i);
    EXPECT_EQ(v.end() - v.begin(), 30);
    EXPECT_EQ(*(v.begin() + 17), 13);
    std::sort(v.begin(), v.end());
    for (int i = 0; i < 30; ++i) EXPECT_EQ(v[i], i + 1);
    const Small& c = v;
    EXPECT_EQ(std::accumulate(c.begin(), c.end(), 0), 30 * 31 / 2);
}

}  // namespace
}  // namespace render
