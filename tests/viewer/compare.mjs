// compare.mjs SPEC.json... - drives Debian's chromium (headless, SwiftShader)
// on the viewer page and checks it against render. Prints one PASS/FAIL
// line per case, details on stderr; exits 0 (the lines carry the verdict).
//
// SPEC: {"url": "http://127.0.0.1:PORT/", "maxMismatch": 0.0005,
//        "cases": [
//          {"name", "file": "encode/x.ssvdag", "camera": "cam.json",
//           "ids": "render.vid", "depth": "render.pfm",
//           "png": "render.png" (optional: colours, with "colours"),
//           "colours": "raw/colours.raw" (optional)},
//          {"name", "file", "expectError": "regex"},
//          {"name", "file", "query": "camera=...", "expectCamera": "cam.json"},
//          {"name", "file", "expectColours": "dir/colours.auto" or "",
//           "expectStatus": "regex" (optional)}]}
// The page draws every voxel, as render does by default, unless a case's
// "query" says lod=N (then render --lod N is the reference).
// A case's "query" is added to the page's URL (what voxdag view
// --camera-file prints); "expectCamera" wants the page's starting camera
// to be the file's, number for number.
// A pixel mismatches when its hit cell differs from render's, or its depth
// differs by more than 1e-4 of the depth (float against double). Their
// share of the pixels either side hits must stay within maxMismatch: the
// page traces in float, so a ray grazing a voxel edge may go either way.
import fs from 'node:fs';
import puppeteer from 'puppeteer-core';
import { PNG } from 'pngjs';

// several specs share one browser (its start is a second or two here)
let spec = null;
const pass = (n, extra = '') => console.log(`PASS ${n}${extra ? ' (' + extra + ')' : ''}`);
const fail = (n, why) => { console.log(`FAIL ${n}`); console.error(`  ${n}: ${why}`); };

function readIds(path) {
  const b = fs.readFileSync(path);
  if (b[0] !== 0x89 || b.toString('latin1', 1, 4) !== 'VID') throw new Error(`${path}: not a voxel-id file`);
  const w = b.readUInt32LE(8), h = b.readUInt32LE(12);
  const ids = new Uint32Array(4 * w * h);
  for (let i = 0; i < 4 * w * h; i++) ids[i] = b.readUInt32LE(16 + 4 * i);
  return { w, h, ids };
}

function readPfm(path) {
  const b = fs.readFileSync(path);
  // three text lines: "Pf", "W H", "-1.0"
  let at = 0;
  const line = () => { const e = b.indexOf(10, at); const s = b.toString('latin1', at, e); at = e + 1; return s.trim(); };
  if (line() !== 'Pf') throw new Error(`${path}: not a greyscale PFM`);
  const [w, h] = line().split(/\s+/).map(Number);
  const scale = Number(line());
  const le = scale < 0;
  const d = new Float32Array(w * h);
  for (let y = 0; y < h; y++) // bottom row first
    for (let x = 0; x < w; x++) {
      const o = at + 4 * ((h - 1 - y) * w + x);
      d[y * w + x] = le ? b.readFloatLE(o) : b.readFloatBE(o);
    }
  return { w, h, d };
}

const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const pages = new Map();
async function pageFor(file, colours, w, h, file2, extra) {
  const key = `${spec.url}|${file}|${file2 || ''}|${colours || ''}|${w}x${h}|${extra || ''}`;
  if (pages.has(key)) return pages.get(key);
  const page = await browser.newPage();
  page.on('pageerror', (e) => console.error('  page error:', e.message));
  const q = new URLSearchParams(extra || '');
  q.set('file', file);
  q.set('size', `${w}x${h}`);
  if (colours) q.set('colours', colours);
  if (file2) { q.set('file2', file2); q.set('diff', '1'); }
  const t0 = Date.now();
  await page.goto(`${spec.url}?${q}`);
  const verdict = await Promise.race([
    page.evaluate(() => window.voxdag.ready),
    new Promise((r) => setTimeout(() => r('timeout'), 30000).unref()),
  ]);
  const info = { page, verdict, error: await page.evaluate(() => window.voxdag.error()), seconds: (Date.now() - t0) / 1000 };
  pages.set(key, info);
  return info;
}

for (const path of process.argv.slice(2)) {
spec = JSON.parse(fs.readFileSync(path, 'utf8'));
for (const c of spec.cases) {
  try {
    if (c.expectError) {
      const p = await pageFor(c.file, c.colours, 64, 48, null, c.query);
      const shown = await p.page.$eval('#status', (e) => e.className === 'error' ? e.textContent : '');
      if (p.verdict === 'error' && new RegExp(c.expectError).test(p.error) && shown)
        pass(c.name);
      else fail(c.name, `verdict ${p.verdict}, error '${p.error}', shown '${shown}', expected /${c.expectError}/`);
      continue;
    }
    if (c.expectColours !== undefined) {
      // no colours in the URL: the page picks the pipeline's own, or
      // falls back to grey saying why (expectStatus)
      const p = await pageFor(c.file, null, 64, 48);
      if (p.verdict !== 'ok') { fail(c.name, `page: ${p.verdict}: ${p.error}`); continue; }
      const got = await p.page.evaluate(() => window.voxdag.stats().views[0].colours);
      const shown = await p.page.$eval('#status', (e) => e.textContent);
      if (got === c.expectColours && (!c.expectStatus || new RegExp(c.expectStatus).test(shown))) pass(c.name);
      else fail(c.name, `colours '${got}', status '${shown}'; expected '${c.expectColours}'${c.expectStatus ? ' and /' + c.expectStatus + '/' : ''}`);
      continue;
    }
    if (c.expectCamera) {
      const want = JSON.parse(fs.readFileSync(c.expectCamera, 'utf8'));
      const p = await pageFor(c.file, null, 64, 48, null, c.query);
      if (p.verdict !== 'ok') { fail(c.name, `page: ${p.verdict}: ${p.error}`); continue; }
      const got = await p.page.evaluate(() => window.voxdag.camera());
      const same = ['eye', 'target', 'up'].every((k) => [0, 1, 2].every((a) => got[k][a] === (want[k] || [0, 1, 0])[a])) &&
        got.fov === (want.fov || 40);
      if (same) pass(c.name); else fail(c.name, `page's camera ${JSON.stringify(got)}, file's ${JSON.stringify(want)}`);
      continue;
    }
    const cam = JSON.parse(fs.readFileSync(c.camera, 'utf8'));
    if (c.file2) {
      // two scenes side by side, each cam.width wide: the pixels marked
      // red must be the ones render --diff counts (same rule: the first
      // hits of the two scenes are not one cell)
      const p = await pageFor(c.file, null, 2 * cam.width, cam.height, c.file2);
      if (p.verdict !== 'ok') { fail(c.name, `page: ${p.verdict}: ${p.error}`); continue; }
      await p.page.evaluate((k) => window.voxdag.setCamera(k), cam);
      const got = await p.page.evaluate(() => window.voxdag.stats().diffPixels);
      const want = c.renderDiff;
      const extra = `page marks ${got}, render --diff ${want}`;
      if (got !== null && Math.abs(got - want) <= Math.max(2, 0.01 * want)) pass(c.name, extra);
      else fail(c.name, extra);
      continue;
    }
    const ref = readIds(c.ids);
    const refD = readPfm(c.depth);
    const p = await pageFor(c.file, c.colours, cam.width, cam.height, null, c.query);
    if (p.verdict !== 'ok') { fail(c.name, `page: ${p.verdict}: ${p.error}`); continue; }
    const got = await p.page.evaluate((k) => window.voxdag.readBack(k), cam);
    const frameMs = await p.page.evaluate((k) => window.voxdag.setCamera(k), cam);
    let hits = 0, bad = 0, badDepth = 0, edge = 0;
    const n = cam.width * cam.height;
    if (ref.w !== cam.width || ref.h !== cam.height) throw new Error(`render wrote ${ref.w}x${ref.h}`);
    for (let i = 0; i < n; i++) {
      const rh = ref.ids[4 * i + 3] !== 0xffffffff, gh = got.ids[4 * i + 3] !== 0xffffffff;
      if (!rh && !gh) continue;
      hits++;
      let same = rh && gh;
      for (let k = 0; same && k < 4; k++) same = ref.ids[4 * i + k] === got.ids[4 * i + k];
      if (!same) {
        bad++;
        // a ray grazing a voxel edge: the neighbouring cell at the same depth
        let near = rh && gh && ref.ids[4 * i + 3] === got.ids[4 * i + 3];
        for (let k = 0; near && k < 3; k++) near = Math.abs(ref.ids[4 * i + k] - got.ids[4 * i + k]) <= 1;
        if (near && Math.abs(refD.d[i] - got.depth[i]) <= 1e-4 * Math.abs(refD.d[i]) + 1e-6) edge++;
        continue;
      }
      const a = refD.d[i], b = got.depth[i];
      if (!(Math.abs(a - b) <= 1e-4 * Math.abs(a) + 1e-6)) { bad++; badDepth++; }
    }
    const share = hits ? bad / hits : 1;
    const extra = `${bad} of ${hits} hit pixels differ (${edge} a neighbouring cell at the same depth, ${badDepth} in depth only), ` +
      `load ${p.seconds.toFixed(1)} s, id pass ${got.ms.toFixed(0)} ms, frame ${frameMs.toFixed(0)} ms`;
    if (hits > 0.02 * n && share <= spec.maxMismatch) pass(c.name, extra);
    else fail(c.name, extra + (hits <= 0.02 * n ? ': the camera sees almost nothing' : ''));
    if (c.png) {
      // render's pixel is the voxel's colour times a shading factor
      // (sRGB-encoded: px = rgb * light^(1/2.2), up to rounding); the page
      // gives the voxel's colour unshaded. Fit the factor per pixel and
      // count pixels whose colour is not that multiple of the page's.
      const refPng = PNG.sync.read(fs.readFileSync(c.png));
      const mine = await p.page.evaluate((k) => window.voxdag.colourImage(k), cam);
      let off = 0, cnt = 0;
      for (let i = 0; i < n; i++) {
        if (ref.ids[4 * i + 3] === 0xffffffff || got.ids[4 * i + 3] === 0xffffffff) continue;
        const a = [0, 1, 2].map((k) => refPng.data[4 * i + k]);
        const b = [0, 1, 2].map((k) => mine[3 * i + k]);
        const sb = b[0] + b[1] + b[2];
        cnt++;
        if (sb === 0) { if (a[0] + a[1] + a[2] > 6) off++; continue; }
        const f = (a[0] + a[1] + a[2]) / sb;
        if (f > 1.05 || [0, 1, 2].some((k) => Math.abs(a[k] - f * b[k]) > 4)) off++;
      }
      const s = `${off} of ${cnt} hit pixels not a multiple of the page's colour`;
      if (cnt && off / cnt <= (spec.maxColourOff || 0.01)) pass(c.name + '_colour', s);
      else fail(c.name + '_colour', s);
    }
  } catch (e) {
    fail(c.name, e.stack || String(e));
  }
}
}
await browser.close();
