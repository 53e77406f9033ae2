#!/usr/bin/env node
// Headless-browser test of a tileset in NASA-AMMOS 3DTilesRendererJS (three.js),
// the second viewer citylod's tiles must load in, offline:
//   - serves a one-page three.js scene, three and 3d-tiles-renderer from
//     tests/node/node_modules and the tileset on 127.0.0.1 (built-in server);
//   - the page registers GLTFExtensionsPlugin with three's meshopt decoder
//     (EXT_meshopt_compression) and the EXT_mesh_features /
//     EXT_structural_metadata extensions (schema by schemaUri);
//   - opens Debian's chromium through playwright-core (SwiftShader WebGL),
//     blocks every request that is not to 127.0.0.1;
//   - waits until the tiles of the initial view load, moves the camera closer
//     and checks that more (deeper) tiles loaded, that no tile failed, and that
//     a loaded mesh carries feature ids whose property table row has a
//     building_id. Saves screenshots and result.json in --out.
// Exit 0 pass, 1 fail, 2 usage, 77 chromium or the packages missing (skip).
//
//   node tests/node/renderer-test.mjs --tileset DIR --out DIR [--chromium /usr/bin/chromium]
//        [--timeout-ms 180000]
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { serveStatic, launch, run } from './browser.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));

const opts = { chromium: '/usr/bin/chromium', timeoutMs: 180000 };
const argv = process.argv.slice(2);
for (let i = 0; i < argv.length; ++i) {
  const a = argv[i];
  if (a === '--tileset') opts.tileset = argv[++i];
  else if (a === '--out') opts.out = argv[++i];
  else if (a === '--chromium') opts.chromium = argv[++i];
  else if (a === '--timeout-ms') opts.timeoutMs = Number(argv[++i]);
  else {
    console.error('unknown argument ' + a);
    process.exit(2);
  }
}
if (!opts.tileset || !opts.out) {
  console.error('usage: renderer-test.mjs --tileset DIR --out DIR');
  process.exit(2);
}
if (!fs.existsSync(opts.chromium)) {
  console.log(`SKIP: chromium not found at ${opts.chromium} (apt-get install chromium)`);
  process.exit(77);
}
const modules = path.join(here, 'node_modules');
for (const p of ['three/build/three.module.js', '3d-tiles-renderer/build/index.three.js']) {
  if (!fs.existsSync(path.join(modules, p))) {
    console.log(`SKIP: ${p} missing: run scripts/install-node-tools.sh`);
    process.exit(77);
  }
}
fs.mkdirSync(opts.out, { recursive: true });
const log = (...a) => console.log('[renderer-test]', ...a);

const page = `<!doctype html>
<html><head><meta charset="utf-8"><title>citylod in 3DTilesRendererJS</title></head>
<body style="margin:0;background:#9bb">
<script type="importmap">{"imports": {
  "three": "/node_modules/three/build/three.module.js",
  "three/addons/": "/node_modules/three/examples/jsm/",
  "3d-tiles-renderer/three": "/node_modules/3d-tiles-renderer/build/index.three.js",
  "3d-tiles-renderer/three/plugins": "/node_modules/3d-tiles-renderer/build/index.three-plugins.js"
}}</script>
<script type="module">
import * as THREE from 'three';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { TilesRenderer } from '3d-tiles-renderer/three';
import { GLTFExtensionsPlugin, GLTFMeshFeaturesExtension, GLTFStructuralMetadataExtension }
  from '3d-tiles-renderer/three/plugins';
const s = window.r3 = { loaded: 0, failed: [], maxDepth: -1, ready: false, error: null, feature: null };
try {
  const renderer = new THREE.WebGLRenderer();
  renderer.setSize(800, 600);
  document.body.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.add(new THREE.AmbientLight(0xffffff, 0.6));
  const sun = new THREE.DirectionalLight(0xffffff, 2);
  scene.add(sun);
  const camera = new THREE.PerspectiveCamera(50, 800 / 600, 0.5, 1e8);
  const tiles = new TilesRenderer('/tileset/tileset.json');
  tiles.registerPlugin(new GLTFExtensionsPlugin({ meshoptDecoder: MeshoptDecoder,
    plugins: [(p) => new GLTFMeshFeaturesExtension(p), (p) => new GLTFStructuralMetadataExtension(p)] }));
  tiles.errorTarget = 16;
  tiles.setCamera(camera);
  tiles.setResolutionFromRenderer(camera, renderer);
  scene.add(tiles.group);
  tiles.addEventListener('load-model', (e) => {
    s.loaded++;
    const d = e.tile && e.tile.internal && typeof e.tile.internal.depth === 'number' ? e.tile.internal.depth
      : (e.tile && typeof e.tile.__depth === 'number' ? e.tile.__depth : -1);
    s.maxDepth = Math.max(s.maxDepth, d);
    if (s.feature) return;
    let meta = e.scene.userData.structuralMetadata || null;
    e.scene.traverse((o) => {
      if (s.feature || !o.userData || !o.userData.meshFeatures) return;
      const md = o.userData.structuralMetadata || meta;
      const info = o.userData.meshFeatures.getFeatureInfo();
      if (!md || !info.length) return;
      const ids = o.geometry.getAttribute('_feature_id_0');
      const fid = ids ? ids.getX(0) : 0;
      const rows = md.getPropertyTableData([info[0].propertyTable], [fid]);
      s.feature = { id: fid, building_id: rows && rows[0] ? rows[0].building_id : undefined,
        rmse: rows && rows[0] ? rows[0].rmse : undefined };
    });
  });
  tiles.addEventListener('load-error', (e) => s.failed.push(String((e.error && e.error.message) || e.error) + ' ' + e.url));
  const sphere = new THREE.Sphere();
  let placed = false;
  s.place = (factor) => {  // camera above the tileset's centre, looking down at an angle
    tiles.getBoundingSphere(sphere);
    const up = sphere.center.clone().normalize();
    const side = new THREE.Vector3(0, 0, 1).cross(up).normalize();
    camera.position.copy(sphere.center).addScaledVector(up, sphere.radius * factor)
      .addScaledVector(side, sphere.radius * factor * 0.5);
    camera.up.copy(up);
    camera.lookAt(sphere.center);
    sun.position.copy(camera.position);
    camera.updateMatrixWorld();
  };
  tiles.addEventListener('load-root-tileset', () => { if (!placed) { placed = true; s.place(8); } });
  const frame = () => {
    camera.updateMatrixWorld();
    tiles.update();
    renderer.render(scene, camera);
    s.ready = placed;
    s.queued = tiles.stats ? (tiles.stats.queued + tiles.stats.downloading + tiles.stats.parsing) : 0;
    requestAnimationFrame(frame);
  };
  frame();
} catch (e) { s.error = String(e && e.stack ? e.stack : e); }
</script></body></html>`;

// ------------------------------------------------------------ server
const serve = () => serveStatic([['/tileset/', path.resolve(opts.tileset)],
  ['/node_modules/three/', path.join(modules, 'three')],
  ['/node_modules/3d-tiles-renderer/', path.join(modules, '3d-tiles-renderer')]], { '/': page, '/index.html': page });

// ------------------------------------------------------------ browser
const result = { ok: false, checks: {}, external_requests: [], console_errors: [], screenshots: [] };
const state = {};
async function settle(pg) {  // the page placed its camera and nothing is queued for a while
  await pg.waitForFunction(() => window.r3 && (window.r3.error || (window.r3.ready && window.r3.loaded > 0)),
    null, { timeout: opts.timeoutMs, polling: 250 });
  let idle = 0;
  const t0 = Date.now();
  while (idle < 6 && Date.now() - t0 < opts.timeoutMs) {
    await pg.waitForTimeout(250);
    idle = (await pg.evaluate(() => window.r3.queued)) === 0 ? idle + 1 : 0;
  }
}
async function main() {
  state.server = await serve();
  log('server', state.server.url);
  Object.assign(state, await launch(opts.chromium, { width: 800, height: 600 }, result));
  const pg = state.page;
  await pg.goto(state.server.url, { waitUntil: 'load' });
  await settle(pg);
  const probe = () => pg.evaluate(() => ({ error: window.r3.error, loaded: window.r3.loaded,
    depth: window.r3.maxDepth, failed: window.r3.failed, feature: window.r3.feature }));
  const s0 = await probe();
  if (s0.error) throw new Error('page error: ' + s0.error);
  result.checks.initial = s0;
  log('initial view:', JSON.stringify(s0));
  await shot(pg, 'r1-overview.png');
  await pg.evaluate(() => window.r3.place(0.6));
  await pg.waitForTimeout(500);
  await settle(pg);
  const s1 = await probe();
  result.checks.zoomed = s1;
  log('zoomed in:', JSON.stringify(s1));
  await shot(pg, 'r2-zoomed.png');
  if (s1.failed.length) throw new Error('tiles failed to load: ' + JSON.stringify(s1.failed.slice(0, 3)));
  if (!(s1.loaded > s0.loaded && s1.depth > s0.depth))
    throw new Error(`no finer tiles after zooming in (models ${s0.loaded} -> ${s1.loaded}, depth ${s0.depth} -> ${s1.depth})`);
  if (!s1.feature || typeof s1.feature.building_id !== 'string' || !s1.feature.building_id.length)
    throw new Error('no building_id through EXT_mesh_features / EXT_structural_metadata: ' + JSON.stringify(s1.feature));
  const errors = result.console_errors.filter((m) => !/favicon/.test(m));
  if (errors.length) throw new Error('console errors: ' + errors.slice(0, 3).join(' | '));
  if (result.external_requests.length) throw new Error('requests left 127.0.0.1: ' + result.external_requests.slice(0, 5).join(', '));
  result.ok = true;
}

async function shot(pg, name) {
  const file = path.join(opts.out, name);
  await pg.screenshot({ path: file });
  result.screenshots.push(file);
}

await run('renderer-test', opts.out, result, state, main);
