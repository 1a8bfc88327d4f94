// shot.mjs URL OUT.png - opens the viewer at URL (what voxdag view prints,
// e.g. with --camera-file's camera) in headless Debian chromium and writes
// the picture the page's "screenshot" button would save; prints the
// page's load and frame times.
import fs from 'node:fs';
import puppeteer from 'puppeteer-core';

const [url, out] = process.argv.slice(2);
const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const page = await browser.newPage();
await page.goto(url);
const verdict = await page.evaluate(() => window.voxdag.ready);
if (verdict !== 'ok') {
  console.error(`shot: ${await page.evaluate(() => window.voxdag.error())}`);
  process.exitCode = 1;
} else {
  const png = await page.evaluate(() => window.voxdag.screenshot());
  fs.writeFileSync(out, Buffer.from(png.replace(/^data:image\/png;base64,/, ''), 'base64'));
  const st = await page.evaluate(() => window.voxdag.stats());
  const v = st.views[0];
  console.log(`${v.path}: ${v.nodes} nodes loaded in ${v.loadMs.toFixed(0)} ms, frame ${st.frameMs.toFixed(0)} ms; wrote ${out}`);
}
await browser.close();
