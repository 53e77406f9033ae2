#!/usr/bin/env python3
"""One line of figures from a val3dity 2.6 JSON report (--report):

  scripts/val3dity-summary.py REPORT.json
  -> buildings valid 27/27, solids valid 90/90, errors {}

Buildings = features of type Building (their chain's +LodTreeModel objects are separate features).
"""
import json, sys
from collections import Counter

r = json.load(open(sys.argv[1]))
b = [f for f in r['features'] if f['type'] == 'Building']
prim = sum(o['total'] for o in r['primitives_overview'])
prim_ok = sum(o['valid'] for o in r['primitives_overview'])
errs = Counter()
for f in r['features']:
    for e in f.get('errors', []):
        errs[e['code']] += 1
print(f"buildings valid {sum(f['validity'] for f in b)}/{len(b)}, solids valid {prim_ok}/{prim}, "
      f"errors {dict(sorted(errs.items()))}")
