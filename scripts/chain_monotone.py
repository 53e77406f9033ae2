#!/usr/bin/env python3
"""Kept chains that get worse when zooming in: for every building of a `citylod tile` output, the
models the tileset keeps (tileset/buildings.json) with their RMSE to the points (report.json e2 x
bbox diagonal / 100); a chain is non-monotone when a kept model is worse than a coarser kept model
by more than TOL metres (default 0.05).

  scripts/chain_monotone.py OUT_DIR [--tol 0.05]
"""
import json, os, sys

out = sys.argv[1]
tol = float(sys.argv[sys.argv.index('--tol') + 1]) if '--tol' in sys.argv else 0.05
b = json.load(open(os.path.join(out, 'tileset', 'buildings.json')))['buildings']
bad = []
worst = []
for bid, rec in sorted(b.items()):
    rp = os.path.join(out, 'work', 'lod', bid, 'report.json')
    if not os.path.exists(rp):
        continue
    r = json.load(open(rp))
    by_step = {m['step']: m for m in r['models']}
    diag = r.get('bbox_diagonal_m', 0)
    rm = []
    for m in rec['models']:
        md = by_step.get(m['step'])
        if md and md.get('e2', -1) >= 0 and diag > 0:
            rm.append(md['e2'] / 100 * diag)
    excess = 0.0
    best = float('inf')
    for x in rm:
        excess = max(excess, x - best)
        best = min(best, x)
    worst.append((excess, bid))
    if excess > tol:
        bad.append(bid)
worst.sort(reverse=True)
print(f'buildings {len(worst)}, non-monotone kept chains ({tol} m) {len(bad)}; worst excess '
      + ', '.join(f'{e:.3f} m {i}' for e, i in worst[:3]))
