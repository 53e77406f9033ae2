#!/usr/bin/env python3
# Share of roof / wall / base area of the LOD models that carries an input colour
# (report.json runs + model PLYs): python3 bench/colour_share.py WORK [x]
# (x: also the exact colours of the finest models by class). BENCHMARKS.md "Colours on the faces".
import json, glob, struct, sys, math
def ply(path):
    b = open(path, 'rb').read()
    h = b.index(b'end_header\n') + len('end_header\n')
    head = b[:h].decode()
    nv = int(head.split('element vertex ')[1].split()[0]); nf = int(head.split('element face ')[1].split()[0])
    o = h; V = []
    for i in range(nv):
        V.append(struct.unpack_from('<3d', b, o)); o += 24
    F = []
    for i in range(nf):
        n = b[o]; o += 1
        F.append(struct.unpack_from('<%di' % n, b, o)); o += 4 * n
    return V, F
def runs(r):
    out = []
    for x in r:
        out += [x[1:] if len(x) == 4 else None] * x[0]
    return out
tot = {}
for rep in sorted(glob.glob(sys.argv[1] + '/lod/*/report.json')):
    d = json.load(open(rep)); ms = d['models']
    for i, m in enumerate(ms):
        V, F = ply(rep.rsplit('/', 1)[0] + '/' + m['file'])
        col = runs(m['colours']['triangles']) if 'colours' in m else [None] * len(F)
        for t, c in zip(F, col):
            a, b_, c_ = V[t[0]], V[t[1]], V[t[2]]
            u = [b_[k] - a[k] for k in range(3)]; v = [c_[k] - a[k] for k in range(3)]
            n = [u[1]*v[2]-u[2]*v[1], u[2]*v[0]-u[0]*v[2], u[0]*v[1]-u[1]*v[0]]
            A = math.sqrt(sum(x*x for x in n)) / 2
            if A == 0: continue
            nz = n[2] / (2 * A)
            cls = 'roof' if nz >= 0.34 else 'base' if nz <= -0.34 else 'wall'
            for scope in (['all', 'finest'] if i == len(ms) - 1 else ['all']):
                k = (scope, cls); tot.setdefault(k, [0, 0]); tot[k][0] += A; tot[k][1] += A if c else 0
for k in sorted(tot):
    print(k, '%.1f m2, coloured %.1f %%' % (tot[k][0], 100 * tot[k][1] / tot[k][0]))
# exact colours of the finest models by class (top 3)
if len(sys.argv) > 2:
    dist = {}
    for rep in sorted(glob.glob(sys.argv[1] + '/lod/*/report.json')):
        d = json.load(open(rep)); m = d['models'][-1]
        V, F = ply(rep.rsplit('/', 1)[0] + '/' + m['file'])
        col = runs(m['colours']['triangles']) if 'colours' in m else [None] * len(F)
        for t, c in zip(F, col):
            a, b_, c_ = V[t[0]], V[t[1]], V[t[2]]
            u = [b_[k] - a[k] for k in range(3)]; v = [c_[k] - a[k] for k in range(3)]
            n = [u[1]*v[2]-u[2]*v[1], u[2]*v[0]-u[0]*v[2], u[0]*v[1]-u[1]*v[0]]
            A = math.sqrt(sum(x*x for x in n)) / 2
            if A == 0: continue
            nz = n[2] / (2 * A)
            cls = 'roof' if nz >= 0.34 else 'base' if nz <= -0.34 else 'wall'
            dist.setdefault(cls, {}); key = tuple(c) if c else None
            dist[cls][key] = dist[cls].get(key, 0) + A
    for cls, dd in dist.items():
        T = sum(dd.values())
        print(cls, ', '.join('%s %.1f %%' % (k, 100 * v / T) for k, v in sorted(dd.items(), key=lambda kv: -kv[1])[:4]))
