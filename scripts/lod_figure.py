#!/usr/bin/env python3
"""One figure per building: its candidate LOD models, coarse to fine.

    scripts/lod_figure.py OUT_DIR PNG [--title TEXT] [--max-panels N] [--azimuth DEG]

OUT_DIR is what `citylod lod INPUT -o OUT_DIR` wrote (report.json and one
OBJ of merged polygons per candidate). Every anchor is drawn (orange frame,
as in the paper's figures) and the interpolations between them (green), at
most --max-panels in all (interpolations thinned evenly when there are more).
Each panel: the model in one fixed oblique parallel view shared by all panels,
faces shaded by their normal, labelled with its step, kind, level, polygon
count and e2. Drawn by gnuplot (pngcairo) from 2D polygons sorted back to
front; otherwise the standard library only.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile


def read_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append(tuple(float(x) for x in line.split()[1:4]))
            elif line.startswith("f "):
                faces.append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
    return verts, faces


def pick(models, max_panels):
    """All anchors, and the interpolations thinned evenly to fit."""
    anchors = [i for i, m in enumerate(models) if m["kind"] == "anchor"]
    interp = [i for i, m in enumerate(models) if m["kind"] != "anchor"]
    room = max(0, max_panels - len(anchors))
    if len(interp) > room:
        interp = [interp[round(k * (len(interp) - 1) / max(1, room - 1))] for k in range(room)] if room else []
    return sorted(set(anchors) | set(interp))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out_dir")
    ap.add_argument("png")
    ap.add_argument("--title", default=None)
    ap.add_argument("--max-panels", type=int, default=24)
    ap.add_argument("--azimuth", type=float, default=-35.0)
    ap.add_argument("--elevation", type=float, default=30.0)
    a = ap.parse_args()
    report = json.load(open(os.path.join(a.out_dir, "report.json")))
    models = report["models"]
    chosen = pick(models, a.max_panels)
    az, el = math.radians(a.azimuth), math.radians(a.elevation)
    # view frame: right, up, towards the viewer
    right = (math.cos(az), math.sin(az), 0.0)
    view = (-math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el))
    up = (
        view[1] * right[2] - view[2] * right[1],
        view[2] * right[0] - view[0] * right[2],
        view[0] * right[1] - view[1] * right[0],
    )
    light = (0.3, -0.5, 0.8)
    ln = math.sqrt(sum(c * c for c in light))
    light = tuple(c / ln for c in light)
    dot = lambda p, q: p[0] * q[0] + p[1] * q[1] + p[2] * q[2]

    meshes = []
    for i in chosen:
        obj = os.path.join(a.out_dir, models[i]["file"].rsplit(".", 1)[0] + ".obj")
        meshes.append((i, read_obj(obj)))
    xs, ys = [], []
    for _, (verts, _) in meshes:
        for v in verts:
            xs.append(dot(v, right))
            ys.append(dot(v, up))
    if not xs:
        sys.exit("lod_figure.py: no model to draw")
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    cols = min(6, len(meshes))
    rows = (len(meshes) + cols - 1) // cols
    pw, ph, label_h, top = 300, 240, 34, 40
    scale = min((pw - 20) / max(1e-9, x1 - x0), (ph - label_h - 20) / max(1e-9, y1 - y0))
    W, H = cols * pw, rows * ph + top
    out = [f'set terminal pngcairo size {W},{H} background rgb "white"',
           f'set output "{a.png}"',
           "unset border; unset tics; unset key",
           "set lmargin at screen 0; set rmargin at screen 1; set tmargin at screen 1; set bmargin at screen 0",
           f"set xrange [0:{W}]; set yrange [{H}:0]"]
    obj = [0]

    def polygon(pts, fill, border, lw):
        obj[0] += 1
        out.append(f"set object {obj[0]} polygon from " +
                   " to ".join(f"{x:.1f},{y:.1f}" for x, y in pts + pts[:1]) +
                   f' front fillcolor rgb "{fill}" fillstyle solid 1.0 border lc rgb "{border}" lw {lw}')

    def label(x, y, text, size):
        out.append(f'set label "{text}" at {x},{y} font ",{size}" noenhanced')

    hexc = lambda c: "#%02x%02x%02x" % c
    title = a.title or os.path.basename(report.get("input", a.out_dir))
    counts = report.get("counts", {})
    label(10, 24, f'{title}: {len(models)} candidates, N_l = {counts.get("level_sets", "?")}, '
          f'P = {counts.get("P", "?")}, S = {counts.get("S", "?")} (shown: {len(meshes)})', 14)
    for k, (i, (verts, faces)) in enumerate(meshes):
        m = models[i]
        ox, oy = (k % cols) * pw, top + (k // cols) * ph
        polys = []
        for f in faces:
            if len(f) < 3:
                continue
            p = [verts[j] for j in f]
            # Newell normal
            n = [0.0, 0.0, 0.0]
            for s in range(len(p)):
                q, r = p[s], p[(s + 1) % len(p)]
                n[0] += (q[1] - r[1]) * (q[2] + r[2])
                n[1] += (q[2] - r[2]) * (q[0] + r[0])
                n[2] += (q[0] - r[0]) * (q[1] + r[1])
            nl = math.sqrt(dot(n, n))
            if nl == 0 or dot(n, view) <= 0:
                continue  # back face
            n = [c / nl for c in n]
            depth = sum(dot(q, view) for q in p) / len(p)
            shade = 0.35 + 0.65 * max(0.0, dot(n, light))
            pts = [(ox + 10 + (dot(q, right) - x0) * scale,
                    oy + ph - label_h - 10 - (dot(q, up) - y0) * scale) for q in p]
            polys.append((depth, pts, shade))
        polys.sort()
        anchor = m["kind"] == "anchor"
        base = (235, 150, 60) if anchor else (110, 180, 110)
        for _, pts, shade in polys:
            c = tuple(int(min(255, b * shade + 20)) for b in base)
            polygon(pts, hexc(c), "#282828", 0.3)
        frame = "#eb7814" if anchor else "#3c963c"
        obj[0] += 1
        out.append(f"set object {obj[0]} rect from {ox + 3},{oy + 3} to {ox + pw - 3},{oy + ph - 3} "
                   f'back fillstyle empty border lc rgb "{frame}" lw 2')
        e2 = m.get("e2", -1)
        kind = "anchor" if anchor else "interp."
        label(ox + 8, oy + ph - 14, f'#{m["step"]} {kind} L{m["level"]}, {m["polygons"]} pol., '
              f'e2 {e2:.3f} %', 9)
    out.append("plot NaN notitle")
    with tempfile.NamedTemporaryFile("w", suffix=".gp", delete=False) as t:
        t.write("\n".join(out) + "\n")
        script = t.name
    try:
        subprocess.run(["gnuplot", script], check=True)
    finally:
        os.unlink(script)


if __name__ == "__main__":
    main()
