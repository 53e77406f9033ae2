#!/usr/bin/python3
"""citylod against roofer as the scene grows: the shared Delft tile copied N x N.

  scripts/scale_bench.py [--grids 1,2,4,8,16] [--citylod EXE] [--threads 2] [--no-roofer]
                         [--las FILE] [--footprints GPKG] [--work DIR] [--keep]

For each N of --grids, ../shared/tools/scale/replicate.py copies the tile and its
footprints N x N (N^2 copies: 1x, 4x, 16x, 64x, 256x), then, one after the other
on the same files, `citylod tile` (3D Tiles + CityJSON) and roofer
(../shared/tools/roofer/run-roofer.sh, LoD 1.2/1.3/2.2), each under GNU time.
Prints one Markdown table row per N as it finishes, then the table: points,
footprints, citylod's stages (split, LOD, assemble+CityJSON from run_report.json),
split M points/s, LOD ms per building, wall, CPU (user+sys), peak RSS (the
largest of the process and its LOD child), output bytes (tiles, tileset JSON,
buildings.json, CityJSON) and per building, fallbacks; roofer's wall, peak RSS and
CityJSON bytes; wall and RSS ratios. Replicas are deleted after their row unless --keep.
"""
import argparse, json, os, re, shutil, subprocess, sys, time

here = os.path.dirname(os.path.abspath(__file__))
root = os.path.dirname(here)
shared = os.path.join(os.path.dirname(root), 'shared')

ap = argparse.ArgumentParser()
ap.add_argument('--grids', default='1,2,4,8,16')
ap.add_argument('--citylod', default=os.path.join(root, 'build', 'app', 'citylod'))
ap.add_argument('--threads', type=int, default=2)
ap.add_argument('--no-roofer', action='store_true')
ap.add_argument('--las', default=os.path.join(shared, 'data', 'delft', 'ahn3_cropped_2.las'))
ap.add_argument('--footprints', default=os.path.join(shared, 'data', 'delft', 'bgt_pand.gpkg'))
ap.add_argument('--work', default='/tmp/citylod-scale-bench')
ap.add_argument('--keep', action='store_true')
a = ap.parse_args()

roofer = os.path.join(shared, 'tools', 'roofer', 'run-roofer.sh')
replicate = os.path.join(shared, 'tools', 'scale', 'replicate.py')
os.makedirs(a.work, exist_ok=True)


def timed(cmd, log):
    """Runs cmd under GNU time: (wall s, user+sys s, max RSS MiB of the largest process)."""
    tf = log + '.time'
    with open(log, 'w') as out:
        t0 = time.monotonic()
        rc = subprocess.call(['/usr/bin/time', '-v', '-o', tf] + cmd, stdout=out, stderr=subprocess.STDOUT)
        wall = time.monotonic() - t0
    txt = open(tf).read()
    if rc != 0:
        sys.exit('scale_bench: %s failed (exit %d), see %s' % (cmd[0], rc, log))
    user = float(re.search(r'User time \(seconds\): ([\d.]+)', txt).group(1))
    sys_ = float(re.search(r'System time \(seconds\): ([\d.]+)', txt).group(1))
    rss = int(re.search(r'Maximum resident set size \(kbytes\): (\d+)', txt).group(1)) / 1024
    return wall, user + sys_, rss


def du(path):
    total = 0
    for d, _, files in os.walk(path):
        for f in files:
            total += os.path.getsize(os.path.join(d, f))
    return total


geojson = os.path.join(a.work, 'footprints.geojson')
if not os.path.exists(geojson):
    subprocess.check_call(['ogr2ogr', '-f', 'GeoJSON', geojson, a.footprints])

header = ('| copies | points (M) | footprints | split s | M pts/s | LOD s | ms/bldg | assemble+CityJSON s '
          '| wall s | CPU s | peak RSS MiB | tiles MB | tileset JSON MB | buildings.json MB | CityJSON MB '
          '| out KB/bldg | fallbacks | roofer wall s | roofer RSS MiB | roofer MB | wall / roofer | RSS / roofer |')
rule = '|' + '|'.join(['---'] * (header.count('|') - 1)) + '|'
rows = []
print(header + '\n' + rule, flush=True)
for n in [int(x) for x in a.grids.split(',')]:
    prefix = os.path.join(a.work, 'rep%d' % n)
    subprocess.check_call([sys.executable, replicate, a.las, geojson, str(n), str(n), prefix],
                          stdout=subprocess.DEVNULL)
    las, fp = prefix + '.las', prefix + '.geojson'
    out = prefix + '.citylod'
    shutil.rmtree(out, ignore_errors=True)
    wall, cpu, rss = timed([a.citylod, 'tile', las, '--crs', 'EPSG:28992', '--footprints', fp,
                            '--footprints-id', 'gml_id', '--threads', str(a.threads), '--out', out,
                            '--quiet'], out + '.log')
    rep = json.load(open(os.path.join(out, 'run_report.json')))
    st = rep['stages']
    points = st['split']['points']
    nfp = len(json.load(open(fp))['features'])
    nb = st['lod']['buildings']
    tiles = du(os.path.join(out, 'tileset', 'tiles'))
    ts_json = sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(os.path.join(out, 'tileset'))
                  for f in fs if f.endswith('.json') and f != 'buildings.json')
    bjson = os.path.getsize(os.path.join(out, 'tileset', 'buildings.json'))
    cj = os.path.getsize(os.path.join(out, 'buildings.city.jsonl'))
    rss_all = max(rss, rep['peak_rss_bytes']['self'] / 2**20, rep['peak_rss_bytes']['children'] / 2**20)
    rest = wall - st['split']['seconds'] - st['lod']['seconds']
    row = [n * n, '%.1f' % (points / 1e6), nfp, '%.1f' % st['split']['seconds'],
           '%.2f' % (points / 1e6 / max(st['split']['seconds'], 1e-9)), '%.1f' % st['lod']['seconds'],
           '%.1f' % (1000 * st['lod']['seconds'] / max(nb, 1)), '%.1f' % rest, '%.1f' % wall, '%.1f' % cpu,
           '%.0f' % rss_all, '%.1f' % (tiles / 1e6), '%.2f' % (ts_json / 1e6), '%.2f' % (bjson / 1e6),
           '%.1f' % (cj / 1e6), '%.1f' % ((tiles + ts_json + bjson + cj) / 1e3 / max(nb, 1)),
           rep['summary']['fallback']]
    if not a.no_roofer:
        rout = prefix + '.roofer'
        shutil.rmtree(rout, ignore_errors=True)
        rwall, _, rrss = timed([roofer, '--lod12', '--lod13', '--lod22', '--srs', 'EPSG:28992',
                                '--id-attribute', 'gml_id', '-j', str(a.threads), las, fp, rout], rout + '.log')
        rbytes = du(rout)
        row += ['%.1f' % rwall, '%.0f' % rrss, '%.1f' % (rbytes / 1e6), '%.2f' % (wall / rwall),
                '%.2f' % (rss_all / rrss)]
        if not a.keep:
            shutil.rmtree(rout, ignore_errors=True)
    else:
        row += ['-'] * 5
    line = '| ' + ' | '.join(str(x) for x in row) + ' |'
    rows.append(line)
    print(line, flush=True)
    if not a.keep:
        shutil.rmtree(out, ignore_errors=True)
        for f in (las, fp):
            os.remove(f)

print('\n' + header + '\n' + rule + '\n' + '\n'.join(rows))
