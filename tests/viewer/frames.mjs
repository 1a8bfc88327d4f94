// frames.mjs URL - the viewer's load and frame times in headless Debian
// chromium (SwiftShader here: a CPU, not a GPU) for make bench
// (tests/bench/viewer_frames.sh): one line per image size, the page's own
// statistics (encoding load, first frame) and three more frames from one
// camera, in milliseconds.
import puppeteer from 'puppeteer-core';

const url = process.argv[2];
const cam = JSON.parse(process.argv[3]);
const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
for (const size of ['256x192', '512x512', '960x540']) {
  const page = await browser.newPage();
  const t0 = Date.now();
  const u = new URL(url);
  u.searchParams.set('size', size);
  await page.goto(u.href);
  const verdict = await page.evaluate(() => window.voxdag.ready);
  if (verdict !== 'ok') {
    console.log(`${size}: ${await page.evaluate(() => window.voxdag.error())}`);
    process.exitCode = 1;
    break;
  }
  const ready = Date.now() - t0;
  const st = await page.evaluate(() => window.voxdag.stats());
  const frames = [];
  for (let i = 0; i < 3; i++) frames.push(await page.evaluate((k) => window.voxdag.setCamera(k), cam));
  frames.sort((a, b) => a - b);
  console.log(`${size.padEnd(8)} page ready ${String(ready).padStart(6)} ms, encoding loaded in ` +
    `${st.views[0].loadMs.toFixed(0).padStart(5)} ms, first frame ${st.frameMs.toFixed(0).padStart(6)} ms, ` +
    `median frame ${frames[1].toFixed(0).padStart(6)} ms (${st.views[0].path}, ${st.views[0].nodes} nodes)`);
  await page.close();
}
await browser.close();
