#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Upper bound for separating mesh_city's buildings without footprints (issue 15 item 4).

From the truth alone (footprints_bgt_local.geojson, truth/<id>.obj roofs): every pair of
buildings whose footprints touch (edges within 0.3 m) is sampled every 0.25 m along the
contact, 0.3 m inside each; a pair counts as separable when more than FRACTION of its
contact points see a roof-height difference of at least STEP metres (or, with --angle,
roof slopes more than ANGLE degrees apart: a valley or a change of roof plane). Buildings joined by
a non-separable contact form groups; the buildings alone are the most any split that
separates buildings by roof steps could leave on their own (geometry only: the scene has
no colours, and its meshes are zipped where buildings meet).

  scripts/mesh_city_separation_bound.py [DATA_DIR] [--step 0.5] [--fraction 0.5]
"""
import argparse
import json
import math


def load_obj(path):
    V, T = [], []
    with open(path) as f:
        for line in f:
            if line.startswith('v '):
                V.append(tuple(map(float, line.split()[1:4])))
            elif line.startswith('f '):
                T.append([int(x.split('/')[0]) - 1 for x in line.split()[1:4]])
    return V, T


def roof_top(mesh, x, y):
    """Highest point of the mesh over (x, y) and the unit normal there, or (None, None)."""
    V, T = mesh
    best, normal = None, None
    for t in T:
        a, b, c = (V[k] for k in t)
        d = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1])
        if abs(d) < 1e-12:
            continue
        l1 = ((b[1] - c[1]) * (x - c[0]) + (c[0] - b[0]) * (y - c[1])) / d
        l2 = ((c[1] - a[1]) * (x - c[0]) + (a[0] - c[0]) * (y - c[1])) / d
        l3 = 1 - l1 - l2
        if min(l1, l2, l3) < -1e-9:
            continue
        z = l1 * a[2] + l2 * b[2] + l3 * c[2]
        if best is None or z > best:
            u = [b[k] - a[k] for k in range(3)]
            v = [c[k] - a[k] for k in range(3)]
            n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
            ln = math.sqrt(sum(x * x for x in n)) or 1.0
            best, normal = z, [x / ln * (1 if n[2] >= 0 else -1) for x in n]
    return best, normal


def seg_dist(p, a, b):
    ab = (b[0] - a[0], b[1] - a[1])
    l2 = ab[0] ** 2 + ab[1] ** 2
    t = max(0.0, min(1.0, ((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / l2)) if l2 > 0 else 0.0
    return math.hypot(p[0] - a[0] - t * ab[0], p[1] - a[1] - t * ab[1])


def inside(ring, p):
    c = False
    for a, b in zip(ring, ring[1:]):
        if (a[1] > p[1]) != (b[1] > p[1]) and p[0] < a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]):
            c = not c
    return c


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('data', nargs='?', default='../shared/data/mesh_city')
    ap.add_argument('--step', type=float, default=0.5)
    ap.add_argument('--fraction', type=float, default=0.5)
    ap.add_argument('--angle', type=float, default=0.0,
                    help='also separable where the roof slopes differ by more (degrees; 0: steps only)')
    a = ap.parse_args()
    feats = json.load(open(a.data + '/footprints_bgt_local.geojson'))['features']
    fp = {f['properties']['id']: f['geometry']['coordinates'][0] for f in feats}
    ids = sorted(fp)
    mesh = {i: load_obj('%s/truth/%s.obj' % (a.data, i)) for i in ids}
    contact = {}  # (i, j) -> [points, points with a small step]
    for i in ids:
        P = fp[i]
        for pa, pb in zip(P, P[1:]):
            L = math.hypot(pb[0] - pa[0], pb[1] - pa[1])
            if L == 0:
                continue
            nx, ny = (pb[1] - pa[1]) / L, -(pb[0] - pa[0]) / L
            n = max(1, int(L / 0.25))
            for s in range(n + 1):
                p = (pa[0] + s / n * (pb[0] - pa[0]), pa[1] + s / n * (pb[1] - pa[1]))
                for j in ids:
                    Q = fp[j]
                    if j == i or min(seg_dist(p, q0, q1) for q0, q1 in zip(Q, Q[1:])) > 0.3:
                        continue
                    for sg in (1, -1):
                        pi = (p[0] - sg * 0.3 * nx, p[1] - sg * 0.3 * ny)
                        pj = (p[0] + sg * 0.3 * nx, p[1] + sg * 0.3 * ny)
                        if inside(P, pi) and inside(Q, pj):
                            break
                    else:
                        continue
                    (zi, ni), (zj, nj) = roof_top(mesh[i], *pi), roof_top(mesh[j], *pj)
                    if zi is None or zj is None:
                        continue
                    c = contact.setdefault(tuple(sorted((i, j))), [0, 0])
                    c[0] += 1
                    same_plane = sum(x * y for x, y in zip(ni, nj)) > math.cos(math.radians(a.angle))
                    c[1] += abs(zi - zj) < a.step and (a.angle <= 0 or same_plane)
    joined = {i: set() for i in ids}
    for (i, j), (n, small) in contact.items():
        if small > a.fraction * n:
            joined[i].add(j)
            joined[j].add(i)
    seen, groups = set(), []
    for i in ids:
        if i in seen:
            continue
        stack, g = [i], []
        seen.add(i)
        while stack:
            x = stack.pop()
            g.append(x)
            for y in sorted(joined[x]):
                if y not in seen:
                    seen.add(y)
                    stack.append(y)
        groups.append(g)
    alone = sum(1 for g in groups if len(g) == 1)
    print('step %.2f m, angle %.0f deg, fraction %.2f: %d touching pairs; group sizes %s; alone %d of %d (%.0f %%)'
          % (a.step, a.angle, a.fraction, len(contact), sorted(len(g) for g in groups), alone, len(ids),
             100.0 * alone / len(ids)))


if __name__ == '__main__':
    main()
