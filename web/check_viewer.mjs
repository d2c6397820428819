// Renders stills of the viewer in Debian's chromium, headless, WebGL through SwiftShader, driven
// by puppeteer-core (24.x: runs on Node 20). Usage:
//   node check_viewer.mjs OUT_DIR EXPORT_DIR SIZE ORTHO mode:frame [mode:frame ...]
// Serves this folder at / and EXPORT_DIR at /export/; writes OUT_DIR/<mode>_<frame>.png and prints
// one JSON line {renderer, files}.
import http from 'node:http';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import puppeteer from 'puppeteer-core';

const here = path.dirname(fileURLToPath(import.meta.url));
const [outDir, exportDir, size, ortho, ...shots] = process.argv.slice(2);
const types = { '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript', '.json': 'application/json',
                '.glb': 'model/gltf-binary', '.exr': 'image/x-exr', '.png': 'image/png' };
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(req.url.split('?')[0]);
  const file = url.startsWith('/export/') ? path.join(exportDir, url.slice(8)) : path.join(here, url);
  fs.readFile(file, (err, data) => {
    if (err) { res.writeHead(404); res.end(); return; }
    res.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream' });
    res.end(data);
  });
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const port = server.address().port;
const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
         '--ignore-gpu-blocklist', `--window-size=${size},${size}`],
});
try {
  const page = await browser.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('requestfailed', (r) => errors.push(`failed ${r.url()}`));
  page.on('response', (r) => { if (r.status() >= 400) errors.push(`${r.status()} ${r.url()}`); });
  await page.setViewport({ width: Number(size), height: Number(size) });
  const q = `glb=/export/tree.glb&bones=/export/bone_anim.json&size=${size}&ortho=${ortho}&frame=0`;
  await page.goto(`http://127.0.0.1:${port}/viewer.html?${q}`, { waitUntil: 'load' });
  try {
    await page.waitForFunction('!!window.viewer', { timeout: 60000 });
    await page.evaluate(() => window.viewer.ready.then(() => true));
  } catch (err) {
    const text = await page.evaluate(() => document.getElementById('status')?.textContent);
    throw new Error(`the viewer did not start (${text}): ${errors.join(' | ')}`);
  }
  const files = [];
  let rendererName = '';
  for (const shot of shots) {
    const [mode, frame] = shot.split(':');
    const r = await page.evaluate((f, m) => window.viewer.render(f, m), Number(frame), mode);
    rendererName = r.renderer;
    const file = path.join(outDir, `${mode}_${frame}.png`);
    fs.writeFileSync(file, Buffer.from(r.png.split(',')[1], 'base64'));
    files.push(file);
  }
  if (errors.length) { console.error(errors.join('\n')); process.exitCode = 1; }
  console.log(JSON.stringify({ renderer: rendererName, files }));
} finally {
  await browser.close();
  server.close();
}
