#!/usr/bin/env node
// Headless-browser test of examples/viewer on a tileset, offline:
//   - serves the viewer, CesiumJS (node_modules/cesium/Build/Cesium) and the
//     tileset on 127.0.0.1, with `citylod serve` (--citylod BIN) or a built-in
//     node server (--node-server);
//   - opens Debian's chromium through playwright-core (fresh profile, SwiftShader
//     WebGL), blocks every request that is not to 127.0.0.1;
//   - waits until all tiles of the initial view load, zooms onto a building,
//     waits again and checks that deeper (finer) tiles loaded and no tileFailed
//     event fired; clicks the building (metadata shown) and forces its coarsest
//     LOD model; saves screenshots and result.json in --out.
// Exit 0 pass, 1 fail, 2 usage, 77 chromium missing (skip).
//
//   node tests/node/viewer-test.mjs --tileset DIR --out DIR [--citylod BIN | --node-server]
//        [--chromium /usr/bin/chromium] [--timeout-ms 120000] [--building ID]
import fs from 'node:fs';
import path from 'node:path';
import { spawn } from 'node:child_process';
import { fileURLToPath } from 'node:url';
import { serveStatic, launch, run } from './browser.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const repo = path.resolve(here, '..', '..');

const opts = { chromium: '/usr/bin/chromium', timeoutMs: 180000, viewer: path.join(repo, 'examples', 'viewer') };
const argv = process.argv.slice(2);
for (let i = 0; i < argv.length; ++i) {
  const a = argv[i];
  if (a === '--tileset') opts.tileset = argv[++i];
  else if (a === '--out') opts.out = argv[++i];
  else if (a === '--citylod') opts.citylod = argv[++i];
  else if (a === '--node-server') opts.nodeServer = true;
  else if (a === '--chromium') opts.chromium = argv[++i];
  else if (a === '--timeout-ms') opts.timeoutMs = Number(argv[++i]);
  else if (a === '--building') opts.building = argv[++i];
  else if (a === '--viewer') opts.viewer = argv[++i];
  else {
    console.error('unknown argument ' + a);
    process.exit(2);
  }
}
if (!opts.tileset || !opts.out || (!opts.citylod && !opts.nodeServer)) {
  console.error('usage: viewer-test.mjs --tileset DIR --out DIR (--citylod BIN | --node-server)');
  process.exit(2);
}
if (!fs.existsSync(opts.chromium)) {
  console.log(`SKIP: chromium not found at ${opts.chromium} (apt-get install chromium)`);
  process.exit(77);
}
fs.mkdirSync(opts.out, { recursive: true });
const cesiumDir = path.join(here, 'node_modules', 'cesium', 'Build', 'Cesium');
const log = (...a) => console.log('[viewer-test]', ...a);

// ------------------------------------------------------------ server
const nodeServer = () => serveStatic([['/tileset/', path.resolve(opts.tileset)], ['/cesium/', cesiumDir], ['/', opts.viewer]]);
function citylodServer() {
  return new Promise((resolve, reject) => {
    const child = spawn(opts.citylod, ['serve', opts.tileset, '--port', '0', '--viewer', opts.viewer,
      '--cesium', cesiumDir], { stdio: ['ignore', 'pipe', 'pipe'] });
    let out = '';
    const timer = setTimeout(() => reject(new Error('citylod serve printed no URL: ' + out)), 15000);
    child.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/http:\/\/127\.0\.0\.1:(\d+)\//);
      if (m) {
        clearTimeout(timer);
        resolve({ url: m[0], stop: () => child.kill('SIGTERM') });
      }
    });
    child.stderr.on('data', (d) => process.stderr.write('[citylod serve] ' + d));
    child.on('exit', (code) => reject(new Error('citylod serve exited with ' + code + ': ' + out)));
  });
}

// ------------------------------------------------------------ browser
const result = { ok: false, checks: {}, external_requests: [], console_errors: [], screenshots: [] };
const state = {};
async function main() {
  state.server = opts.nodeServer ? await nodeServer() : await citylodServer();
  log('server', state.server.url);
  Object.assign(state, await launch(opts.chromium, { width: 1024, height: 768 }, result));
  const page = state.page;

  const t0 = Date.now();
  await page.goto(state.server.url, { waitUntil: 'load' });
  await page.waitForFunction(() => window.citylod && (window.citylod.ready || window.citylod.error),
    null, { timeout: opts.timeoutMs, polling: 250 });
  const s0 = await page.evaluate(() => ({ error: window.citylod.error, loaded: window.citylod.loadedTiles,
    depth: window.citylod.maxLoadedDepth, failed: window.citylod.failed,
    webgl2: window.citylod.viewer.scene.context.webgl2 }));
  if (s0.error) throw new Error('viewer error: ' + s0.error);
  result.checks.initial = { ...s0, seconds: (Date.now() - t0) / 1000 };
  log('initial view:', JSON.stringify(result.checks.initial));
  await page.waitForTimeout(500);
  await shot(page, '1-overview.png');

  // Zoom onto a building: finer tiles must load.
  const id = opts.building || (await page.evaluate(async () => Object.keys((await window.citylod.loadIndex()).buildings)[0]));
  const before = await page.evaluate(() => window.citylod.allTilesLoadedCount);
  await page.evaluate((b) => window.citylod.flyToBuilding(b, 45), id);
  await page.waitForFunction((n) => window.citylod.allTilesLoadedCount > n && window.citylod.tileset.tilesLoaded,
    before, { timeout: opts.timeoutMs, polling: 250 });
  await page.waitForTimeout(500);
  const s1 = await page.evaluate(() => ({ loaded: window.citylod.loadedTiles, depth: window.citylod.maxLoadedDepth,
    visibleDepth: window.citylod.maxVisibleDepth, failed: window.citylod.failed }));
  result.checks.zoomed = { building: id, ...s1 };
  log('zoomed in:', JSON.stringify(result.checks.zoomed));
  await shot(page, '2-zoomed.png');
  if (!(s1.depth > s0.depth)) throw new Error(`no finer tiles loaded after zooming in (depth ${s0.depth} -> ${s1.depth})`);
  if (s1.failed.length) throw new Error('tileFailed: ' + JSON.stringify(s1.failed));

  // Click the building: its metadata appears.
  const pos = await page.evaluate((b) => window.citylod.screenPositionOf(b), id);
  if (!pos) throw new Error('building centre not on screen');
  await page.mouse.click(pos.x, pos.y);
  await page.waitForFunction(() => window.citylod.selected, null, { timeout: 20000, polling: 100 });
  const sel = await page.evaluate(() => window.citylod.selected);
  result.checks.clicked = sel;
  log('clicked:', JSON.stringify(sel));
  if (!sel.properties || sel.properties.building_id === undefined) throw new Error('no metadata for the clicked feature');
  await page.waitForTimeout(300);
  await shot(page, '3-selected.png');

  // Force the coarsest model of the building (the slider's job).
  await page.evaluate((b) => window.citylod.forceModel(b, 0), id);
  await page.waitForFunction(() => window.citylod.forced && window.citylod.forced.ready, null, { timeout: 30000 });
  await page.waitForTimeout(500);
  result.checks.forced = await page.evaluate(() => window.citylod.forced);
  log('forced:', JSON.stringify(result.checks.forced));
  // The building's own feature of the forced model (its tile's glb, the
  // building alone shown) is what a click at the building's centre picks: a
  // wrong axis convention would swing it away from there.
  const fpos = await page.evaluate((b) => window.citylod.screenPositionOf(b), id);
  const hit = fpos && (await page.evaluate((p) => window.citylod.pickAt(p), fpos));
  result.checks.forced_pick = hit;
  log('forced pick:', JSON.stringify(hit));
  if (!hit || !hit.forced || hit.building_id !== String(id))
    throw new Error('the forced model of ' + id + ' is not at the building (picked ' + JSON.stringify(hit) + ')');
  await shot(page, '4-forced-coarsest.png');
  const final = await page.evaluate(() => window.citylod.failed);
  if (final.length) throw new Error('tileFailed: ' + JSON.stringify(final));
  if (result.external_requests.length) throw new Error('requests left 127.0.0.1: ' + result.external_requests.slice(0, 5).join(', '));
  result.ok = true;
}

async function shot(page, name) {
  const file = path.join(opts.out, name);
  await page.screenshot({ path: file });
  result.screenshots.push(file);
}

await run('viewer-test', opts.out, result, state, main);
