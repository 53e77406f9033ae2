#!/usr/bin/env node
// What a CesiumJS client loads for a tileset's overview (issue 28 item 4):
// headless chromium (SwiftShader WebGL, offline), a fresh page whose camera
// is set before the first frame to look straight down at the centre of the
// tileset's bounding sphere from RANGE metres (default 720), with the
// tileset's default maximumScreenSpaceError (16). Waits until every tile of
// that view is loaded, then prints one line and writes --json:
//   seconds      page start -> all tiles of the view loaded
//   tiles        tiles selected in the last frame, their depth
//   triangles    triangles selected (Cesium3DTilesetStatistics)
//   geometry_mb  decoded geometry in memory (statistics.geometryByteLength)
//   download_mb  bytes the browser received from /tileset/ (every request)
//   requests     requests to /tileset/ (tileset JSON, glbs, schema)
// A benchmark, not a test: it fails only when the page does.
//
//   node tests/node/overview-bench.mjs --tileset DIR [--range 720] [--json FILE]
//        [--chromium /usr/bin/chromium] [--timeout-ms 300000]
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { serveStatic, launch } from './browser.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const opts = { chromium: '/usr/bin/chromium', range: 720, timeoutMs: 300000 };
const argv = process.argv.slice(2);
for (let i = 0; i < argv.length; ++i) {
  const a = argv[i];
  if (a === '--tileset') opts.tileset = argv[++i];
  else if (a === '--range') opts.range = Number(argv[++i]);
  else if (a === '--json') opts.json = argv[++i];
  else if (a === '--chromium') opts.chromium = argv[++i];
  else if (a === '--timeout-ms') opts.timeoutMs = Number(argv[++i]);
  else {
    console.error('unknown argument ' + a);
    process.exit(2);
  }
}
if (!opts.tileset || !(opts.range > 0)) {
  console.error('usage: overview-bench.mjs --tileset DIR [--range M] [--json FILE]');
  process.exit(2);
}
if (!fs.existsSync(opts.chromium)) {
  console.log(`SKIP: chromium not found at ${opts.chromium} (apt-get install chromium)`);
  process.exit(77);
}
const cesiumDir = path.join(here, 'node_modules', 'cesium', 'Build', 'Cesium');

const page = `<!doctype html><html><head><meta charset="utf-8">
<script src="/cesium/Cesium.js"></script>
<link href="/cesium/Widgets/widgets.css" rel="stylesheet">
<style>html,body,#c{margin:0;width:100%;height:100%;overflow:hidden}</style></head>
<body><div id="c"></div><script>
(async () => {
  const out = (window.bench = { done: false, error: null });
  try {
    const t0 = performance.now();
    Cesium.Ion.defaultAccessToken = '';
    const viewer = new Cesium.Viewer('c', {
      baseLayer: false, terrainProvider: new Cesium.EllipsoidTerrainProvider(),
      baseLayerPicker: false, geocoder: false, timeline: false, animation: false,
      sceneModePicker: false, navigationHelpButton: false, fullscreenButton: false,
      infoBox: false, selectionIndicator: false, homeButton: false, msaaSamples: 1 });
    const tileset = await Cesium.Cesium3DTileset.fromUrl('/tileset/tileset.json');
    viewer.scene.primitives.add(tileset);
    const c = Cesium.Cartographic.fromCartesian(tileset.boundingSphere.center);
    viewer.camera.setView({
      destination: Cesium.Cartesian3.fromRadians(c.longitude, c.latitude, c.height + ${opts.range}),
      orientation: { heading: 0, pitch: -Cesium.Math.PI_OVER_TWO, roll: 0 } });
    let frameTiles = 0, frameDepth = 0, lastTiles = 0, lastDepth = 0;
    const depthOf = (t) => { let d = 0; for (let p = t.parent; p; p = p.parent) ++d; return d; };
    tileset.tileVisible.addEventListener((t) => { ++frameTiles; frameDepth = Math.max(frameDepth, depthOf(t)); });
    viewer.scene.postRender.addEventListener(() => {
      lastTiles = frameTiles; lastDepth = frameDepth; frameTiles = 0; frameDepth = 0; });
    await new Promise((resolve) => tileset.allTilesLoaded.addEventListener(resolve));
    const seconds = (performance.now() - t0) / 1000;
    await new Promise((resolve) => { viewer.scene.requestRender(); setTimeout(resolve, 500); });
    const s = tileset.statistics;
    Object.assign(out, { seconds, tiles: lastTiles, depth: lastDepth,
      triangles: s.numberOfTrianglesSelected, geometry_mb: s.geometryByteLength / 1e6,
      radius_m: tileset.boundingSphere.radius, done: true });
  } catch (e) {
    out.error = String(e && e.stack ? e.stack : e);
    out.done = true;
  }
})();
</script></body></html>`;

const result = { external_requests: [], console_errors: [] };
const server = await serveStatic([['/tileset/', path.resolve(opts.tileset)], ['/cesium/', cesiumDir]],
  { '/': page });
let code = 1;
let browser = null;
try {
  browser = await launch(opts.chromium, { width: 1024, height: 768 }, result);
  let bytes = 0, requests = 0;
  const pending = [];
  browser.page.on('requestfinished', (req) => {
    if (!new URL(req.url()).pathname.startsWith('/tileset/')) return;
    ++requests;
    pending.push(req.sizes().then((sz) => { bytes += sz.responseBodySize; }).catch(() => {}));
  });
  await browser.page.goto(server.url, { waitUntil: 'load' });
  await browser.page.waitForFunction(() => window.bench && window.bench.done, null,
    { timeout: opts.timeoutMs, polling: 250 });
  const b = await browser.page.evaluate(() => window.bench);
  if (b.error) throw new Error(b.error);
  await Promise.all(pending);
  const r = { range_m: opts.range, ...b, download_mb: bytes / 1e6, requests };
  delete r.done;
  delete r.error;
  console.log(`overview from ${opts.range} m: ${r.seconds.toFixed(1)} s, ${r.tiles} tiles (depth ${r.depth}), ` +
    `${r.triangles} triangles, ${r.geometry_mb.toFixed(1)} MB decoded, ${r.download_mb.toFixed(1)} MB ` +
    `downloaded in ${requests} requests (tileset radius ${r.radius_m.toFixed(0)} m)`);
  if (opts.json) fs.writeFileSync(opts.json, JSON.stringify(r, null, 1) + '\n');
  code = 0;
} catch (e) {
  console.error('overview-bench: ' + (e && e.stack ? e.stack : e));
} finally {
  try { if (browser) await browser.context.close(); } catch (e) { /* ignore */ }
  if (browser) fs.rmSync(browser.userDataDir, { recursive: true, force: true });
  server.stop();
}
process.exit(code);
