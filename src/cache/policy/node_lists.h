#pragma once
// The node slab and intrusive doubly linked lists the list-based replacement policies share (LRU,
// level-LRU, CLOCK, ARC, S3-FIFO; impl/). Nodes live in one vector and are addressed by 32-bit
// index; a freed node is reused before a new one is made, the last freed first. Each list is a ring
// through a sentinel node, nodes 0 .. lists-1: a sentinel's `next` is its list's front, its `prev`
// its back. A policy declares its Node — `key`, `prev`, `next` and its own fields — and keeps the
// order of its own operations (which decides its eviction order); this holds the pointer work.
//
// Complexity: every operation O(1) (alloc amortised). Thread-safety: none (a policy's owner
// serialises it, i_replacement.h).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "cache/policy/i_replacement.h"

namespace vtsim {

template <class Node>
class NodeSlab {
 public:
  // `sentinels` empty rings, nodes 0 .. sentinels-1 (a CLOCK's ring has none: its hand is its entry).
  explicit NodeSlab(std::uint32_t sentinels = 0) : nodes_(sentinels) {
    for (std::uint32_t i = 0; i < sentinels; ++i) nodes_[i].prev = nodes_[i].next = i;
  }

  Node& operator[](std::uint32_t n) { return nodes_[n]; }
  const Node& operator[](std::uint32_t n) const { return nodes_[n]; }

  // A node holding `key`: the node freed last, else a new one (default fields). Its other fields
  // are as its last use left them; the caller sets what it reads.
  std::uint32_t alloc(std::uint64_t key) {
    std::uint32_t n;
    if (!free_.empty()) {
      n = free_.back();
      free_.pop_back();
    } else {
      n = static_cast<std::uint32_t>(nodes_.size());
      nodes_.emplace_back();
    }
    nodes_[n].key = key;
    return n;
  }
  // Frees n (out of every list already).
  void release(std::uint32_t n) {
    nodes_[n].key = kNoKey;
    free_.push_back(n);
  }
  // Takes n out of its ring; its own prev and next are left as they were.
  void unlink(std::uint32_t n) {
    const Node& x = nodes_[n];
    nodes_[x.prev].next = x.next;
    nodes_[x.next].prev = x.prev;
  }
  // Puts n into `at`'s ring just after it (after a sentinel: its list's front) or just before it
  // (before a sentinel: the back).
  void insert_after(std::uint32_t at, std::uint32_t n) {
    nodes_[n].prev = at;
    nodes_[n].next = nodes_[at].next;
    nodes_[nodes_[at].next].prev = n;
    nodes_[at].next = n;
  }
  void insert_before(std::uint32_t at, std::uint32_t n) {
    nodes_[n].next = at;
    nodes_[n].prev = nodes_[at].prev;
    nodes_[nodes_[at].prev].next = n;
    nodes_[at].prev = n;
  }

 private:
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> free_;
};

// Lists that keep each one's node count and weight (a node's `size`, in the owner's unit: bytes
// for RAM, 1 a page): ARC's T1, T2, B1, B2 and S3-FIFO's S, M, G. Node adds `size` and `list` (the
// list it is in; a sentinel's is its own index).
template <class Node, std::size_t Lists>
class WeightedLists {
 public:
  WeightedLists() : slab_(static_cast<std::uint32_t>(Lists)) {
    for (std::uint32_t i = 0; i < Lists; ++i) slab_[i].list = static_cast<decltype(Node::list)>(i);
  }

  Node& operator[](std::uint32_t n) { return slab_[n]; }
  const Node& operator[](std::uint32_t n) const { return slab_[n]; }
  std::uint32_t alloc(std::uint64_t key) { return slab_.alloc(key); }
  void release(std::uint32_t n) { slab_.release(n); }

  std::uint64_t weight(std::size_t list) const { return weight_[list]; }
  std::uint64_t count(std::size_t list) const { return count_[list]; }
  // The list's front (newest) and back (oldest) node; the sentinel itself when it is empty.
  std::uint32_t front(std::uint8_t list) const { return slab_[list].next; }
  std::uint32_t back(std::uint8_t list) const { return slab_[list].prev; }

  // Takes n out of its list, and its size out of the list's weight.
  void unlink(std::uint32_t n) {
    slab_.unlink(n);
    weight_[slab_[n].list] -= slab_[n].size;
    --count_[slab_[n].list];
  }
  // n, weighing `size`, into `list` at its front (newest) or its back (oldest).
  void push_front(std::uint32_t n, std::uint8_t list, std::uint64_t size) {
    place(n, list, size);
    slab_.insert_after(list, n);
  }
  void push_back(std::uint32_t n, std::uint8_t list, std::uint64_t size) {
    place(n, list, size);
    slab_.insert_before(list, n);
  }

 private:
  void place(std::uint32_t n, std::uint8_t list, std::uint64_t size) {
    slab_[n].list = list;
    slab_[n].size = size;
    weight_[list] += size;
    ++count_[list];
  }

  NodeSlab<Node> slab_;
  std::uint64_t weight_[Lists] = {};
  std::uint64_t count_[Lists] = {};
};

}  // namespace vtsim
