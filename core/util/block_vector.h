#pragma once

// A sequence stored in fixed-size blocks. Unlike std::vector it never moves its elements while
// growing, so growing costs neither a copy nor, for a moment, the memory of both the old and
// the new array (the light vertices of a VCM iteration are hundreds of MB at 512 x 512), and
// clear() keeps the blocks for the next round. Element i is block i / kBlockSize, slot
// i % kBlockSize: two dependent loads, as for a vector of pointers, but no per-element pointer.

#include <compare>
#include <cstddef>
#include <iterator>
#include <type_traits>
#include <utility>
#include <vector>

namespace render {

template <class T, size_t kBlockBits = 12>
class BlockVector {
  public:
    static constexpr size_t kBlockSize = size_t(1) << kBlockBits;

    BlockVector() = default;

    T& operator[](size_t i) { return blocks_[i >> kBlockBits][i & (kBlockSize - 1)]; }
    const T& operator[](size_t i) const { return blocks_[i >> kBlockBits][i & (kBlockSize - 1)]; }
    size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    // Blocks allocated (used or kept for later), for memory accounting in tests.
    size_t block_count() const { return blocks_.size(); }

    template <class... Args>
    T& emplace_back(Args&&... args) {
        const size_t block = size_ >> kBlockBits;
        if (block == blocks_.size()) {
            blocks_.emplace_back();
            blocks_.back().reserve(kBlockSize);
        }
        // A block's capacity is exactly kBlockSize and never exceeded: no reallocation.
        T& added = blocks_[block].emplace_back(std::forward<Args>(args)...);
        ++size_;
        return added;
    }
    void push_back(T&& value) { emplace_back(std::move(value)); }
    void push_back(const T& value) { emplace_back(value); }

    // Destroys the elements; the blocks' memory stays for the next elements.
    void clear() {
        for (std::vector<T>& block : blocks_) block.clear();
        size_ = 0;
    }
    // Destroys the elements of block b only, so that callers can destroy blocks in parallel
    // (destroying touches every element's memory); clear() must follow.
    void clear_block(size_t b) { blocks_[b].clear(); }

    template <class Value>
    class Iterator {
      public:
        using iterator_category = std::random_access_iterator_tag;
        using value_type = std::remove_const_t<Value>;
        using difference_type = std::ptrdiff_t;
        using pointer = Value*;
        using reference = Value&;

        Iterator() = default;
        Iterator(std::conditional_t<std::is_const_v<Value>, const BlockVector, BlockVector>* owner,
                 size_t index)
            : owner_(owner), index_(index) {}
        reference operator*() const { return (*owner_)[index_]; }
        pointer operator->() const { return &(*owner_)[index_]; }
        reference operator[](difference_type n) const { return (*owner_)[index_ + n]; }
        Iterator& operator++() { return ++index_, *this; }
        Iterator operator++(int) { return Iterator(owner_, index_++); }
        Iterator& operator--() { return --index_, *this; }
        Iterator operator--(int) { return Iterator(owner_, index_--); }
        Iterator& operator+=(difference_type n) { return index_ += n, *this; }
        Iterator& operator-=(difference_type n) { return index_ -= n, *this; }
        friend Iterator operator+(Iterator it, difference_type n) { return it += n; }
        friend Iterator operator+(difference_type n, Iterator it) { return it += n; }
        friend Iterator operator-(Iterator it, difference_type n) { return it -= n; }
        friend difference_type operator-(const Iterator& a, const Iterator& b) {
            return difference_type(a.index_) - difference_type(b.index_);
        }
        friend bool operator==(const Iterator& a, const Iterator& b) {
            return a.index_ == b.index_;
        }
        friend auto operator<=>(const Iterator& a, const Iterator& b) {
            return a.index_ <=> b.index_;
        }

      private:
        std::conditional_t<std::is_const_v<Value>, const BlockVector, BlockVector>* owner_ =
            nullptr;
        size_t index_ = 0;
    };
    using iterator = Iterator<T>;
    using const_iterator = Iterator<const T>;

    iterator begin() { return iterator(this, 0); }
    iterator end() { return iterator(this, size_); }
    const_iterator begin() const { return const_iterator(this, 0); }
    const_iterator end() const { return const_iterator(this, size_); }

  private:
    std::vector<std::vector<T>> blocks_;  // each reserved to kBlockSize
    size_t size_ = 0;
};

}  // namespace render
