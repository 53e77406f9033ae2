#!/usr/bin/env python3
"""Makes examples/delft_small/delft_small.las: a small crop of the AHN3 tile
shared/data/delft/ahn3_cropped_2.las (LAS 1.2, point format 1, EPSG:28992 +
NAP heights, AHN3 is CC0).

The crop is an axis-aligned window across the full width of the tile whose
north and south edges are placed so that as few BGT building footprints
(shared/data/delft/bgt_pand.sqlite) as possible are cut, and that holds
30k-60k points. Point records are copied byte for byte (same scale/offset),
so coordinates and attributes are exactly those of the source. Standard
library only:

    python3 scripts/make_example.py [SOURCE.las] [BGT.sqlite] [OUT.las]
"""
import os
import sqlite3
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DATA = os.path.normpath(os.path.join(ROOT, "..", "shared", "data", "delft"))


def read_las(path):
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] != b"LASF":
        sys.exit(f"{path}: not a LAS file")
    header_size, = struct.unpack_from("<H", data, 94)
    offset, = struct.unpack_from("<I", data, 96)
    pf = data[104] & 0x3F
    rl, = struct.unpack_from("<H", data, 105)
    n, = struct.unpack_from("<I", data, 107)
    scale = struct.unpack_from("<3d", data, 131)
    off = struct.unpack_from("<3d", data, 155)
    if pf != 1 or data[24:26] != b"\x01\x02":
        sys.exit(f"{path}: expected LAS 1.2 point format 1")
    return data, header_size, offset, rl, n, scale, off


def footprints(path):
    """Bounding boxes of the BGT footprints (WKB polygons / multipolygons)."""
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    boxes = []
    for (blob,) in con.execute("SELECT GEOMETRY FROM buildingpart"):
        xs, ys = [], []
        parse_wkb(bytes(blob), 0, xs, ys)
        if xs:
            boxes.append((min(xs), min(ys), max(xs), max(ys)))
    return boxes


def parse_wkb(b, i, xs, ys):
    bo = "<" if b[i] == 1 else ">"
    t, = struct.unpack_from(bo + "I", b, i + 1)
    i += 5
    has_z = (t & 0x80000000) != 0 or (t // 1000) == 1
    base = (t & 0xFFFF) % 1000
    dim = 3 if has_z else 2
    if base == 3:  # polygon
        nr, = struct.unpack_from(bo + "I", b, i)
        i += 4
        for _ in range(nr):
            npt, = struct.unpack_from(bo + "I", b, i)
            i += 4
            for _ in range(npt):
                c = struct.unpack_from(bo + "%dd" % dim, b, i)
                xs.append(c[0])
                ys.append(c[1])
                i += 8 * dim
    elif base == 6:  # multipolygon
        ng, = struct.unpack_from(bo + "I", b, i)
        i += 4
        for _ in range(ng):
            i = parse_wkb(b, i, xs, ys)
    else:
        raise ValueError(f"unsupported WKB type {t}")
    return i


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(DATA, "ahn3_cropped_2.las")
    bgt = sys.argv[2] if len(sys.argv) > 2 else os.path.join(DATA, "bgt_pand.sqlite")
    out = sys.argv[3] if len(sys.argv) > 3 else os.path.join(ROOT, "examples", "delft_small", "delft_small.las")
    data, header_size, offset, rl, n, scale, off = read_las(src)
    if offset + n * rl > len(data):
        sys.exit(f"{src}: truncated")

    ys = []
    cls = []
    for k in range(n):
        _, y = struct.unpack_from("<ii", data, offset + k * rl)
        ys.append(y * scale[1] + off[1])
        cls.append(data[offset + k * rl + 15] & 0x1F)
    classes = sorted(set(cls))
    by_class = {c: sorted(y for y, k in zip(ys, cls) if k == c) for c in classes}
    xs_min = min(struct.unpack_from("<i", data, offset + k * rl)[0] for k in range(n)) * scale[0] + off[0]
    xs_max = max(struct.unpack_from("<i", data, offset + k * rl)[0] for k in range(n)) * scale[0] + off[0]
    y_lo, y_hi = min(ys), max(ys)
    ys_sorted = sorted(ys)

    boxes = [b for b in footprints(bgt) if b[2] > xs_min and b[0] < xs_max and b[3] > y_lo and b[1] < y_hi]

    import bisect

    def count_between(a, b, arr=None):
        arr = ys_sorted if arr is None else arr
        return bisect.bisect_left(arr, b) - bisect.bisect_left(arr, a)

    best = None
    step = 0.5
    y0 = y_lo
    while y0 < y_hi:
        for h in [x * 1.0 for x in range(20, 90)]:
            y1 = y0 + h
            if y1 > y_hi:
                break
            cnt = count_between(y0, y1)
            if cnt < 30000 or cnt > 60000:
                continue
            cut = sum(1 for b in boxes if (b[1] < y0 < b[3]) or (b[1] < y1 < b[3]))
            whole = sum(1 for b in boxes if b[1] >= y0 and b[3] <= y1)
            if not (4 <= whole <= 10):
                continue
            if any(count_between(y0, y1, by_class[c]) == 0 for c in classes):
                continue  # keep every class of the source
            building = count_between(y0, y1, by_class.get(6, []))
            key = (cut, -building)
            if best is None or key < best[0]:
                best = (key, y0, y1, cnt, whole, cut)
        y0 += step
    if best is None:
        sys.exit("no window with 30k-60k points and 4-10 whole footprints")
    _, y0, y1, cnt, whole, cut = best

    recs = bytearray()
    mn = [float("inf")] * 3
    mx = [float("-inf")] * 3
    by_return = [0] * 5
    for k in range(n):
        if y0 <= ys[k] < y1:
            r = data[offset + k * rl: offset + (k + 1) * rl]
            recs += r
            xyz = struct.unpack_from("<3i", r, 0)
            for a in range(3):
                v = xyz[a] * scale[a] + off[a]
                mn[a] = min(mn[a], v)
                mx[a] = max(mx[a], v)
            ret = r[14] & 0x07
            if 1 <= ret <= 5:
                by_return[ret - 1] += 1
    m = len(recs) // rl

    h = bytearray(data[:227])
    h[26:58] = b"citylod".ljust(32, b"\0")
    h[58:90] = b"citylod scripts/make_example.py".ljust(32, b"\0")
    struct.pack_into("<H", h, 94, 227)
    struct.pack_into("<I", h, 96, 227)  # no VLRs: the source has no CRS record either
    struct.pack_into("<I", h, 100, 0)
    struct.pack_into("<I", h, 107, m)
    struct.pack_into("<5I", h, 111, *by_return)
    struct.pack_into("<6d", h, 179, mx[0], mn[0], mx[1], mn[1], mx[2], mn[2])
    tmp = out + ".tmp.%d" % os.getpid()
    with open(tmp, "wb") as f:
        f.write(h)
        f.write(recs)
    os.replace(tmp, out)
    print(f"{out}: {m} points, y in [{y0:.2f}, {y1:.2f}), x in [{xs_min:.2f}, {xs_max:.2f}], "
          f"{whole} whole footprints, {cut} cut by the window edges, {os.path.getsize(out)} bytes")


if __name__ == "__main__":
    main()
