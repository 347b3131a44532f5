#!/usr/bin/env python3
"""Converts an Unreal-style virtual-texture feedback dump to a vtsim feedback trace (docs/feedback.md).

Input: CSV lines `frame,page_id,count` (what FVirtualTextureFeedbackBufferDesc with bPageAndCount
holds: one (packed page request, sample count) pair per distinct page; frame = the frame's index).
The packed request is decoded with the bit layout given below: x, y, level, space fields. The
defaults are the layout of UE 4.2x's VirtualTextureCommon.ush (vPageX 12 bits, vPageY 12 bits,
vLevel 4 bits, SpaceID 4 bits, low to high); check it against your engine's shader and pass
--layout if it differs. Pages of other spaces than --space are dropped.

    python3 scripts/feedback_from_unreal.py dump.csv out.vtfb --texture 16384x16384 --tile 128 --fps 60

Standard library only: zstd through ctypes on the system's libzstd (a vtsim dependency).
"""
import argparse, csv, ctypes, ctypes.util, struct, sys


def fnv1a64(b, h=0xcbf29ce484222325):
    for c in b:
        h = ((h ^ c) * 0x100000001b3) & 0xFFFFFFFFFFFFFFFF
    return h


def varint(v):
    out = bytearray()
    while v >= 0x80:
        out.append((v & 0x7F) | 0x80)
        v >>= 7
    out.append(v)
    return bytes(out)


def zigzag(v):
    return (v << 1) ^ (v >> 63) if v < 0 else v << 1


def zstd_compress(raw):
    lib = ctypes.CDLL(ctypes.util.find_library("zstd") or "libzstd.so.1")
    lib.ZSTD_compressBound.restype = ctypes.c_size_t
    lib.ZSTD_compress.restype = ctypes.c_size_t
    lib.ZSTD_isError.restype = ctypes.c_uint
    cap = lib.ZSTD_compressBound(ctypes.c_size_t(len(raw)))
    dst = ctypes.create_string_buffer(cap)
    n = lib.ZSTD_compress(dst, ctypes.c_size_t(cap), raw, ctypes.c_size_t(len(raw)), 9)
    if lib.ZSTD_isError(ctypes.c_size_t(n)):
        sys.exit("feedback_from_unreal: zstd failed")
    return dst.raw[:n]


def mip_levels(w, h):
    n, m = 1, max(w, h)
    while m > 1:
        m, n = (m + 1) // 2, n + 1
    return n


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dump")
    ap.add_argument("out")
    ap.add_argument("--texture", required=True, help="WxH level-0 texels of the virtual texture")
    ap.add_argument("--tile", type=int, default=128, help="page payload texels a side")
    ap.add_argument("--fps", type=float, default=60.0)
    ap.add_argument("--layout", default="12,12,4,4", help="bits of x,y,level,space, low to high")
    ap.add_argument("--space", type=int, default=0)
    ap.add_argument("--feedback", default="0x0", help="WxH of the feedback buffer (information)")
    a = ap.parse_args()
    W, H = (int(v) for v in a.texture.lower().split("x"))
    fw, fh = (int(v) for v in a.feedback.lower().split("x"))
    bx, by, bl, bs = (int(v) for v in a.layout.split(","))
    frames = {}
    with open(a.dump, newline="") as f:
        for line, row in enumerate(csv.reader(f), 1):
            if not row or row[0].strip().startswith("#") or row[0].strip() == "frame":
                continue
            fr, pid, cnt = int(row[0]), int(row[1], 0), int(row[2])
            x, y = pid & ((1 << bx) - 1), (pid >> bx) & ((1 << by) - 1)
            lv, sp = (pid >> (bx + by)) & ((1 << bl) - 1), (pid >> (bx + by + bl)) & ((1 << bs) - 1)
            if sp != a.space or cnt <= 0:
                continue
            t = frames.setdefault(fr, {})
            t[(lv, x, y)] = t.get((lv, x, y), 0) + cnt
    levels = mip_levels(W, H)
    head = b"VTSIMFB1" + struct.pack("<IIQQIIIIIIII", 1, 0, W, H, a.tile, levels, 1, fw, fh, 0, 0, 0) + struct.pack("<d", a.fps)
    out = bytearray(head + struct.pack("<Q", fnv1a64(head)))
    order = sorted(frames)
    for b0 in range(0, len(order), 64):  # blocks of 64 frames
        raw = bytearray()
        for i, fr in enumerate(order[b0:b0 + 64]):
            raw += bytes([2 | 4]) + struct.pack("<d", (b0 + i) / a.fps)  # fresh, measured; no pose
            tiles = sorted(frames[fr].items())
            raw += varint(len(tiles))
            pl, px, py = 0, 0, 0
            for (lv, x, y), cnt in tiles:
                raw += varint(0) + varint(lv - pl) + varint(zigzag(x - px)) + varint(zigzag(y - py)) + varint(cnt)
                pl, px, py = lv, x, y
        comp = zstd_compress(bytes(raw))
        n = len(order[b0:b0 + 64])
        out += b"BLK1" + struct.pack("<IQIIQ", n, b0, len(raw), len(comp), fnv1a64(raw)) + comp
    end = b"END1" + struct.pack("<IQ", 0, len(order))
    out += end + struct.pack("<Q", fnv1a64(end))
    with open(a.out, "wb") as f:
        f.write(out)


if __name__ == "__main__":
    main()
