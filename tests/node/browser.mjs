// Shared by the headless viewer tests (viewer-test.mjs, renderer-test.mjs):
// a static server on 127.0.0.1 and Debian's chromium through playwright-core
// (fresh profile, SwiftShader WebGL, every request not to 127.0.0.1 blocked
// and recorded in result.external_requests; console errors recorded).
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import http from 'node:http';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const mime = { '.html': 'text/html', '.js': 'text/javascript', '.css': 'text/css', '.json': 'application/json',
  '.glb': 'model/gltf-binary', '.png': 'image/png', '.jpg': 'image/jpeg', '.svg': 'image/svg+xml',
  '.wasm': 'application/wasm', '.xml': 'application/xml' };

/// Serves the files under each [prefix, dir] of `roots` (first match wins);
/// `pages` maps a path to a text/html body served as is.
export function serveStatic(roots, pages = {}) {
  const server = http.createServer((req, res) => {
    const p = decodeURIComponent(new URL(req.url, 'http://x').pathname);
    if (pages[p] !== undefined) {
      res.writeHead(200, { 'Content-Type': 'text/html' });
      res.end(pages[p]);
      return;
    }
    for (const [prefix, dir] of roots) {
      if (!p.startsWith(prefix)) continue;
      const file = path.resolve(dir, '.' + (p === '/' ? '/index.html' : p.slice(prefix.length - 1)));
      if (!file.startsWith(dir) || !fs.existsSync(file) || !fs.statSync(file).isFile()) break;
      res.writeHead(200, { 'Content-Type': mime[path.extname(file)] || 'application/octet-stream' });
      fs.createReadStream(file).pipe(res);
      return;
    }
    res.writeHead(404);
    res.end('not found');
  });
  return new Promise((resolve) => server.listen(0, '127.0.0.1', () => resolve({
    url: `http://127.0.0.1:${server.address().port}/`, stop: () => server.close() })));
}

/// Chromium at `chromium` with a viewport; returns { context, page, userDataDir }.
export async function launch(chromiumPath, viewport, result) {
  const { chromium } = require('playwright-core');
  const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'citylod-chromium-'));
  const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: chromiumPath,
    headless: true,
    viewport,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
  });
  await context.route('**/*', (route) => {
    const u = new URL(route.request().url());
    if (u.hostname === '127.0.0.1' || u.protocol === 'data:' || u.protocol === 'blob:') return route.continue();
    result.external_requests.push(u.href);
    return route.abort();
  });
  const page = context.pages()[0] || (await context.newPage());
  page.on('console', (m) => {
    if (m.type() === 'error') result.console_errors.push(m.text());
  });
  page.on('pageerror', (e) => result.console_errors.push('pageerror: ' + e.message));
  return { context, page, userDataDir };
}

/// Runs `main`, then closes the browser and the server, writes result.json in
/// `out` and exits 0 (pass) or 1; `state` holds { context, server, userDataDir }.
export async function run(name, out, result, state, main) {
  let code = 1;
  try {
    await main();
    code = 0;
  } catch (e) {
    result.error = String(e && e.stack ? e.stack : e);
    console.error(`[${name}] FAIL: ` + result.error);
  } finally {
    try { if (state.context) await state.context.close(); } catch (e) { /* ignore */ }
    try { if (state.server) state.server.stop(); } catch (e) { /* ignore */ }
    if (state.userDataDir) fs.rmSync(state.userDataDir, { recursive: true, force: true });
    fs.writeFileSync(path.join(out, 'result.json'), JSON.stringify(result, null, 1));
    console.log(`[${name}]`, result.ok ? 'PASS' : 'FAIL', 'result in', path.join(out, 'result.json'));
  }
  process.exit(code);
}
