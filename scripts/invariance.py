#!/usr/bin/env python3
"""Position invariance of a replicated scene (../shared/tools/scale/replicate.py): the buildings
`<id>_<i>_<j>` of a work directory are copies of one building; every copy must get the same
models (number, triangles per model, volumes to 1e-3 m3).

  scripts/invariance.py WORK [--json]

Prints, per original building, whether all copies agree, and a summary line:
  buildings N, identical in all copies K (P %), RMSE spread of the finest model p50/p90/max (m)
"""
import json, os, re, sys, statistics

work = sys.argv[1]
lod = os.path.join(work, 'lod')
groups = {}
for b in sorted(os.listdir(lod)):
    m = re.match(r'^(.*)_(\d+)_(\d+)$', b)
    rp = os.path.join(lod, b, 'report.json')
    if not m or not os.path.exists(rp):
        continue
    r = json.load(open(rp))
    models = r.get('models', [])
    sig = (r.get('status'), tuple((md['triangles'], round(md['volume'], 3)) for md in models))
    rmse = None
    if models and models[-1].get('e2', -1) >= 0:
        rmse = models[-1]['e2'] / 100 * r.get('bbox_diagonal_m', 0)
    groups.setdefault(m.group(1), []).append((b, sig, rmse, r.get('status')))
same = 0
spreads = []
for g, copies in sorted(groups.items()):
    sigs = {c[1] for c in copies}
    ok = len(sigs) == 1
    same += ok
    rm = [c[2] for c in copies if c[2] is not None]
    spread = (max(rm) - min(rm)) if rm else 0.0
    spreads.append(spread)
    if not ok:
        fb = sum(1 for c in copies if c[3] != 'ok')
        print(f'{g}: {len(sigs)} different model sets over {len(copies)} copies, finest RMSE spread {spread:.3f} m, {fb} fallbacks')
n = len(groups)
spreads.sort()
def q(p):
    return spreads[min(len(spreads) - 1, int(p * len(spreads)))] if spreads else 0.0
print(f'buildings {n}, identical in all copies {same} ({100.0 * same / max(n, 1):.1f} %), '
      f'finest RMSE spread p50 {q(0.5):.3f} p90 {q(0.9):.3f} max {spreads[-1] if spreads else 0:.3f} m')
