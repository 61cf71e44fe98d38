// The WebGL2 viewer of a finished session in a real browser (run by tests/web/test_viewer.cpp): Debian's headless
// chromium (WebGL2 on SwiftShader) opens the console's URL, then /viewer for the session, draws captured view VIEW
// and prints its canvas as a PNG (base64) for the test to compare with `vdrig render`; then the photograph, the
// difference and an orbit frame must draw too, with no console error. At VIEW, a click on camera pixel (CLICK_X,
// CLICK_Y) must show the texel inspector's plot of the texel there.
//   node viewer_test.mjs URL CHROMIUM PROFILE_DIR SESSION VIEW CLICK_X CLICK_Y
import { runInChromium } from './harness.mjs';

const [url, chromium, profile, session, view, clickX, clickY] = process.argv.slice(2);
const seen = { consoleErrors: [], steps: [] };
const args = ['--use-angle=swiftshader', '--enable-unsafe-swiftshader'];
await runInChromium({ chromium, profile, args, timeoutMs: 30000, seen }, async (page) => {
  await page.goto(url, { waitUntil: 'domcontentloaded' });  // the token becomes the cookie
  // The console's list links the complete session's viewer and report.
  await page.waitForSelector(`tr[data-session="${session}"] a[href^="/viewer"]`);
  seen.links = await page.$$eval(`tr[data-session="${session}"] a`, (as) => as.map((a) => a.getAttribute('href')));
  const origin = new URL(page.url()).origin;
  const t0 = Date.now();
  await page.goto(origin + '/viewer?session=' + encodeURIComponent(session), { waitUntil: 'domcontentloaded' });
  await page.waitForFunction(() => document.body.dataset.state === 'drawn' || document.body.dataset.state === 'error');
  seen.firstDrawMs = Date.now() - t0;
  seen.error = await page.$eval('#viewer-error', (el) => el.textContent);
  if (seen.error) throw new Error('viewer: ' + seen.error);
  seen.status = await page.$eval('#viewer-status', (el) => el.textContent);
  const drawAt = async (v, display) => {
    const before = await page.evaluate(() => Number(document.body.dataset.draws));
    await page.evaluate((vv, dd) => {
      document.getElementById('view').value = vv;
      document.getElementById('display').value = dd;
      document.getElementById('display').dispatchEvent(new Event('change'));
    }, String(v), String(display));
    await page.waitForFunction((n) => Number(document.body.dataset.draws) > n, {}, before);
    return page.$eval('#gl', (c) => ({ view: c.dataset.view, display: Number(c.dataset.display), width: c.width,
                                       height: c.height, png: c.toDataURL('image/png').split(',')[1] }));
  };
  seen.render = await drawAt(view, 0);
  // A click at a camera pixel of that view: the canvas is scaled by CSS, so the pixel's centre in page coordinates.
  const box = await page.$eval('#gl', (c) => {
    const r = c.getBoundingClientRect();
    return { left: r.left, top: r.top, sx: r.width / c.width, sy: r.height / c.height };
  });
  await page.mouse.click(box.left + (Number(clickX) + 0.5) * box.sx, box.top + (Number(clickY) + 0.5) * box.sy);
  await page.waitForFunction(() => {
    const img = document.getElementById('texel-plot');
    return img.dataset.texel && !img.hidden && img.complete && img.naturalWidth > 0;
  }).catch(async (e) => {
    throw new Error('no texel plot: ' + await page.$eval('#texel-caption', (el) => el.textContent) + ': ' + e);
  });
  seen.texel = await page.$eval('#texel-plot', (img) => ({
    texel: img.dataset.texel, pixel: img.dataset.pixel.split(',').map(Number), naturalWidth: img.naturalWidth,
    src: img.getAttribute('src'), caption: document.getElementById('texel-caption').textContent }));
  seen.photo = await drawAt(view, 1);
  seen.difference = await drawAt(view, 2);
  for (const k of ['photo', 'difference']) seen[k] = { display: seen[k].display, png: seen[k].png };
  seen.orbit = await drawAt('orbit', 0);
  seen.orbit = { view: seen.orbit.view, png: seen.orbit.png };
  seen.statusAfter = await page.$eval('#viewer-status', (el) => el.textContent);
});
