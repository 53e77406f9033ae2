#!/usr/bin/env python3
"""Validates a CityJSONSeq file against the official CityJSON 2.0 JSON schemas
(cityjson.schema.json for the first line, cityjsonfeature.schema.json for the
others, with the files they reference), all read from SCHEMA_DIR (the
`schemas/` folder of github.com/cityjson/specs). Needs python3-jsonschema >= 4.18
(referencing). Prints the errors and "schema errors: N features: M"; exit 1 when
N > 0, 2 when the schemas or the modules are missing.

usage: cityjson_schema.py SCHEMA_DIR FILE.city.jsonl
"""
import glob
import json
import sys

try:
    from jsonschema import Draft7Validator
    from referencing import Registry, Resource
except ImportError as e:
    print("missing python module:", e)
    sys.exit(2)

d = sys.argv[1]
res = {}
if len(sys.argv) != 3:
    print(__doc__)
    sys.exit(2)
for f in glob.glob(d + '/*.schema.json'):
    s = json.load(open(f))
    res[s['$id']] = Resource.from_contents(s)
reg = Registry().with_resources(res.items())
tops = [k for k in res if k.endswith('/cityjson.schema.json')]
if not tops:
    print('no cityjson.schema.json in', d)
    sys.exit(2)
base = tops[0].rsplit('/', 1)[0]
hv = Draft7Validator(res[base + '/cityjson.schema.json'].contents, registry=reg)
fv = Draft7Validator(res[base + '/cityjsonfeature.schema.json'].contents, registry=reg)
lines = open(sys.argv[2]).read().splitlines()
errs = 0
for e in hv.iter_errors(json.loads(lines[0])):
    errs += 1; print('header:', e.message[:200], list(e.path)[:6])
for i, l in enumerate(lines[1:]):
    for e in fv.iter_errors(json.loads(l)):
        errs += 1
        if errs < 10: print('feature', i + 1, e.message[:200], list(e.path)[:8])
print('schema errors:', errs, 'features:', len(lines) - 1)
sys.exit(1 if errs else 0)
