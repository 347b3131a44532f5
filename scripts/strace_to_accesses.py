#!/usr/bin/env python3
"""Converts `strace -f -y -e trace=openat,read,pread64,lseek` logs of a real program into a vtsim
access file (docs/cache.md, "Cache simulation on access files"): one access per 4 KiB block of a
regular file that a read() or pread64() returned bytes from, key = the first 8 bytes of
BLAKE2b(path, block number), size = the block's bytes: 4096, less for a file's tail block (the
file's end taken as the furthest byte any read returned), so a key keeps one size. read() offsets follow each (pid, fd): openat starts at 0, lseek moves, read advances.
Reads of pipes, sockets and ttys are skipped; so are files read through mmap (not system calls).

Usage: strace_to_accesses.py OUT STRACE_LOG...   (the logs in the order they were recorded)
"""
import hashlib
import re
import sys

BLOCK = 4096
LINE = re.compile(r'^(\d+) +(openat|read|pread64|lseek)\((.*)\) += (-?\d+)(?:<(.*)>)?')
FD = re.compile(r'^(\d+)<([^>]*)>')


def key_of(path, block):
    h = hashlib.blake2b(f'{path}\0{block}'.encode(), digest_size=8).digest()
    k = int.from_bytes(h, 'little')
    return 0 if k == (1 << 64) - 1 else k


def main():
    out_path, logs = sys.argv[1], sys.argv[2:]
    offsets, ends, blocks = {}, {}, []
    for log in logs:
        offsets.clear()
        for line in open(log, errors='replace'):
            m = LINE.match(line)
            if not m:
                continue
            pid, call, args, ret = m.group(1), m.group(2), m.group(3), int(m.group(4))
            if call == 'openat':
                if ret >= 0:
                    offsets[(pid, ret)] = 0
                continue
            f = FD.match(args)
            if not f:
                continue
            fd, path = int(f.group(1)), f.group(2)
            if call == 'lseek':
                if ret >= 0:
                    offsets[(pid, fd)] = ret
                continue
            if not path.startswith('/') or ret <= 0:
                continue
            if call == 'pread64':
                off = int(args.rsplit(',', 1)[1])
            else:
                off = offsets.get((pid, fd), 0)
                offsets[(pid, fd)] = off + ret
            end = off + ret
            ends[path] = max(ends.get(path, 0), end)
            for b in range(off // BLOCK, (end - 1) // BLOCK + 1):
                blocks.append((path, b))
    keys = {}
    with open(out_path, 'w') as out:
        out.write('# vtsim accesses: file reads of a real program recorded with strace (scripts/strace_to_accesses.py)\n')
        for path, b in blocks:
            k = keys.get((path, b))
            if k is None:
                k = keys[(path, b)] = key_of(path, b)
            out.write(f'{k:#x} {min(BLOCK, ends[path] - b * BLOCK)}\n')
    print(f'{len(blocks)} accesses of {len(keys)} blocks of {len(ends)} files written to {out_path}', file=sys.stderr)


if __name__ == '__main__':
    main()
