#!/usr/bin/env python3
"""Small, obviously correct cache simulators, written from libCacheSim's semantics as read in its
source (cache/cache.c cache_get_base; eviction/LRU.c, FIFO.c, Clock.c, Belady.c): a hit changes no
size; on a miss an object larger than the cache is not admitted; otherwise objects are evicted
until the new one fits, then it is inserted. Used by tests/test_cachesim.cpp to cross-check
`vtsim cachesim` miss for miss. NOT libCacheSim itself: an independent reference.

s3fifo_lcs and arc_lcs restate libCacheSim's S3FIFO.c (commit 035d832) and ARC.c (commit
0b517e0) as read, rule for rule, where they differ from vtsim's `s3fifo` and `arc`: docs/cache.md
measures the effect of those differences with them. They are not asserted equal to vtsim's.

Usage: cachesim_reference.py ACCESS_FILE UNIT(objects|bytes) CAP[,CAP...] POLICY[,POLICY...]
Prints one line per (policy, capacity): policy capacity requests misses miss_bytes
"""
import sys
from collections import OrderedDict


def read_accesses(path):
    out = []
    with open(path) as f:
        for line in f:
            line = line.split('#', 1)[0].split()
            if not line or line[0] == 'frame':
                continue
            key = int(line[0], 0)
            size = int(line[1]) if len(line) > 1 else 1
            out.append((key, size))
    return out


def lru(seq, cap, move_on_hit=True):
    cache, used, misses, mbytes = OrderedDict(), 0, 0, 0
    for key, size in seq:
        if key in cache:
            if move_on_hit:
                cache.move_to_end(key)  # the end is the most recent
            continue
        misses += 1
        mbytes += size
        if size > cap:
            continue
        while used + size > cap:
            _, s = cache.popitem(last=False)
            used -= s
        cache[key] = size
        used += size
    return misses, mbytes


def fifo(seq, cap):
    return lru(seq, cap, move_on_hit=False)


def clock(seq, cap):
    # Clock.c: a FIFO; a hit sets the 1-bit counter; eviction takes the oldest, reinserting at the
    # head (counter cleared) every one whose counter is set.
    queue, freq, size_of, used, misses, mbytes = OrderedDict(), {}, {}, 0, 0, 0
    for key, size in seq:
        if key in queue:
            freq[key] = 1
            continue
        misses += 1
        mbytes += size
        if size > cap:
            continue
        while used + size > cap:
            old = next(iter(queue))
            if freq[old]:
                freq[old] = 0
                queue.move_to_end(old)
                continue
            del queue[old]
            used -= size_of.pop(old)
            del freq[old]
        queue[key] = True
        freq[key] = 0
        size_of[key] = size
        used += size
    return misses, mbytes


def belady(seq, cap, skip_never=False):
    # Furthest next use first; keys never used again have next use infinity (ties: any order
    # gives the same count with unit sizes, which is all this reference is used for).
    n = len(seq)
    nxt, later = [n] * n, {}
    for i in range(n - 1, -1, -1):
        nxt[i] = later.get(seq[i][0], n)
        later[seq[i][0]] = i
    cache, used, misses, mbytes = {}, 0, 0, 0  # key -> [next use, size]
    for i, (key, size) in enumerate(seq):
        if key in cache:
            cache[key][0] = nxt[i]
            continue
        misses += 1
        mbytes += size
        if size > cap or (skip_never and nxt[i] == n):
            continue
        while used + size > cap:
            victim = max(cache, key=lambda k: cache[k][0])
            used -= cache.pop(victim)[1]
        cache[key] = [nxt[i], size]
        used += size
    return misses, mbytes


def s3fifo_lcs(seq, cap, keep_freq=False, admit_large=False, main_first=True, vtsim_ghost=False):
    # S3FIFO.c: small 10% (int of cap * 0.1), main the rest, ghost int(cap * 0.9) bytes; a miss
    # not in the ghost enters small, except that before the first eviction a full small sends it
    # to main; an object of size >= small's is not admitted unless it was a ghost; a hit adds 1
    # to freq; evicting small: freq >= 2 moves the object to main (a new object: freq 0), else it
    # leaves into the ghost; evicting main: freq >= 1 reinserts with min(freq, 3) - 1.
    # Each keyword turns one of those rules into vtsim's: keep_freq (a promoted object keeps its
    # freq), admit_large (any object up to the cache's size enters small), main_first=False
    # (always small), vtsim_ghost (the ghost weighs up to main's share).
    small_cap = int(cap * 0.10)
    main_cap = cap - small_cap
    ghost_cap = main_cap if vtsim_ghost else int(cap * 0.90)
    small, main, ghost = OrderedDict(), OrderedDict(), OrderedDict()  # key -> size, first = oldest
    freq = {}
    used = {'s': 0, 'm': 0, 'g': 0}
    state = {'has_evicted': False}
    misses = mbytes = 0

    def ghost_put(key, size):
        if size > ghost_cap:
            return
        while used['g'] + size > ghost_cap:
            _, s = ghost.popitem(last=False)
            used['g'] -= s
        ghost[key] = size
        used['g'] += size

    def evict_small():
        while used['s'] > 0:
            key, size = next(iter(small.items()))
            del small[key]
            used['s'] -= size
            if freq[key] >= 2:
                main[key] = size
                used['m'] += size
                if not keep_freq:
                    freq[key] = 0
            else:
                del freq[key]
                ghost_put(key, size)
                return

    def evict_main():
        while used['m'] > 0:
            key, size = next(iter(main.items()))
            del main[key]
            if freq[key] >= 1:
                main[key] = size
                freq[key] = min(freq[key], 3) - 1
            else:
                used['m'] -= size
                del freq[key]
                return

    for key, size in seq:
        if key in small or key in main:
            freq[key] += 1
            continue
        on_ghost = key in ghost
        if on_ghost:
            used['g'] -= ghost.pop(key)
        misses += 1
        mbytes += size
        if (size > small_cap and not admit_large) or size > cap:  # S3FIFO_can_insert
            continue
        while used['s'] + used['m'] + size > cap:
            state['has_evicted'] = True
            if used['m'] > main_cap or used['s'] == 0:
                evict_main()
            else:
                evict_small()
        if on_ghost:
            main[key] = size
            used['m'] += size
        elif size >= small_cap and not admit_large:
            continue
        elif main_first and not state['has_evicted'] and used['s'] >= small_cap:
            main[key] = size
            used['m'] += size
        else:
            small[key] = size
            used['s'] += size
        freq[key] = 0
    return misses, mbytes


def arc_lcs(seq, cap, real_p=False):
    # ARC.c: p moves by max(|B2| // |B1|, 1) (integer quotient of the byte sizes), whatever the
    # object's size; a ghost hit runs REPLACE at once; then objects are evicted while the new one
    # does not fit: if |T1| + |B1| + size > c, B1's LRU ghost is dropped and REPLACE runs (T1's
    # LRU dropped without a ghost when |T1| >= c), else B2's LRU ghost is dropped when the
    # directory holds >= 2c, then REPLACE. An object larger than the cache: not admitted (ARC.c
    # as read does not check; vtsim's semantics here). real_p: p moves by size * the real ratio
    # (vtsim's rule) instead.
    T1, B1, T2, B2 = OrderedDict(), OrderedDict(), OrderedDict(), OrderedDict()  # last = MRU
    sz = {'T1': 0, 'B1': 0, 'T2': 0, 'B2': 0}
    lists = {'T1': T1, 'B1': B1, 'T2': T2, 'B2': B2}
    st = {'p': 0}
    misses = mbytes = 0

    def pop_lru(name):
        key, size = lists[name].popitem(last=False)
        sz[name] -= size
        return key, size

    def put(name, key, size):
        lists[name][key] = size
        sz[name] += size

    def replace(in_b2):
        if sz['T1'] > 0 and (sz['T1'] > st['p'] or (sz['T1'] == st['p'] and in_b2)) or not T2:
            put('B1', *pop_lru('T1'))
        else:
            put('B2', *pop_lru('T2'))

    for key, size in seq:
        if key in T1:
            put('T2', key, size)
            sz['T1'] -= T1.pop(key)
            continue
        if key in T2:
            T2.move_to_end(key)
            continue
        misses += 1
        mbytes += size
        in_b1, in_b2 = key in B1, key in B2
        if size > cap:
            continue
        if in_b1:
            st['p'] = min(st['p'] + (size * max(sz['B2'] / sz['B1'], 1) if real_p else max(sz['B2'] // sz['B1'], 1)), cap)
            if T1 or T2:
                replace(False)
            sz['B1'] -= B1.pop(key)
        elif in_b2:
            st['p'] = max(st['p'] - (size * max(sz['B1'] / sz['B2'], 1) if real_p else max(sz['B1'] // sz['B2'], 1)), 0)
            if T1 or T2:
                replace(True)
            sz['B2'] -= B2.pop(key)
        while sz['T1'] + sz['T2'] + size > cap:
            if sz['T1'] + sz['B1'] + size > cap:
                if sz['T1'] < cap and B1:
                    pop_lru('B1')
                    replace(in_b2)
                else:
                    pop_lru('T1')
            else:
                if sz['T1'] + sz['B1'] + sz['T2'] + sz['B2'] >= 2 * cap and B2:
                    pop_lru('B2')
                replace(in_b2)
        put('T2' if in_b1 or in_b2 else 'T1', key, size)
    return misses, mbytes


POLICIES = {
    'lru': lru,
    'fifo': fifo,
    'clock': clock,
    'belady': belady,
    'belady_reused': lambda s, c: belady(s, c, skip_never=True),
    's3fifo_lcs': s3fifo_lcs,
    's3fifo_lcs_keep_freq': lambda s, c: s3fifo_lcs(s, c, keep_freq=True),
    's3fifo_lcs_admit_large': lambda s, c: s3fifo_lcs(s, c, admit_large=True),
    's3fifo_lcs_small_first': lambda s, c: s3fifo_lcs(s, c, main_first=False),
    's3fifo_lcs_vtsim_ghost': lambda s, c: s3fifo_lcs(s, c, vtsim_ghost=True),
    's3fifo_vtsim_rules': lambda s, c: s3fifo_lcs(s, c, True, True, False, True),
    'arc_lcs': arc_lcs,
    'arc_real_p': lambda s, c: arc_lcs(s, c, real_p=True),
}


def main():
    path, unit, caps, policies = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
    seq = read_accesses(path)
    if unit == 'objects':
        seq = [(k, 1) for k, _ in seq]
    for p in policies.split(','):
        for c in caps.split(','):
            misses, mbytes = POLICIES[p](seq, int(c))
            print(p, c, len(seq), misses, mbytes)


if __name__ == '__main__':
    main()
