// The web console's screenshots for the README and docs/web.md (`./vdrig.sh screenshots`): Debian's headless
// chromium on a running `vdrig serve` whose vdrigd drives the simulated rig. Starts a session from the form and
// shoots the page mid-capture (progress, hemisphere, thumbnail, journal); then, when the sessions folder holds the
// fitted session SHOWCASE, its viewer at a captured view as render and as difference.
//   node screenshots.mjs URL CHROMIUM PROFILE_DIR OUT_DIR [SHOWCASE [VIEW]]
import puppeteer from 'puppeteer-core';

const [url, chromium, profile, outDir, showcase, showcaseView] = process.argv.slice(2);
const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  userDataDir: profile,
  args: ['--no-sandbox', '--no-first-run', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
         '--disable-dev-shm-usage', '--hide-scrollbars'],
});
try {
  const page = await browser.newPage();
  page.setDefaultTimeout(60000);
  await page.setViewport({ width: 1280, height: 900 });
  await page.goto(url, { waitUntil: 'domcontentloaded' });
  await page.waitForSelector('#daemon.up');
  const fill = async (name, value) => page.$eval(`input[name="${name}"]`, (el, v) => { el.value = v; }, value);
  await fill('session', 'shot-' + Date.now().toString(36));
  await fill('scheme', 'spiral:120:2@80');
  await fill('bracket', 'auto');
  await page.click('#start-form button[type="submit"]');
  // Mid-capture: a third of the views done, a thumbnail and the journal's tail shown.
  await page.waitForFunction(() => {
    const p = document.getElementById('progress');
    return Number(p.value) >= Number(p.max) / 3 && document.getElementById('thumbnail').naturalWidth > 0 &&
      document.getElementById('log-tail').textContent.length > 0;
  });
  await page.click('#home').catch(() => {});  // refused while running: the page shows the daemon's "busy"
  await new Promise((r) => setTimeout(r, 600));
  await page.screenshot({ path: `${outDir}/web_console.png` });
  console.log(`screenshot: ${outDir}/web_console.png`);
  await page.click('#pause');
  await page.waitForFunction(() => document.getElementById('state').textContent === 'paused');

  if (showcase) {
    const origin = new URL(page.url()).origin;
    await page.setViewport({ width: 1280, height: 760 });
    await page.goto(`${origin}/viewer?session=${encodeURIComponent(showcase)}`, { waitUntil: 'domcontentloaded' });
    await page.waitForFunction(() => ['drawn', 'error'].includes(document.body.dataset.state));
    const error = await page.$eval('#viewer-error', (el) => el.textContent);
    if (error) throw new Error('viewer: ' + error);
    const show = async (view, display, file) => {
      const before = await page.evaluate(() => Number(document.body.dataset.draws));
      await page.evaluate((v, d) => {
        const select = document.getElementById('view');
        select.value = [...select.options].some((o) => o.value === v) ? v : select.options[select.options.length - 1].value;
        document.getElementById('display').value = d;
        document.getElementById('display').dispatchEvent(new Event('change'));
      }, String(view), String(display));
      await page.waitForFunction((n) => Number(document.body.dataset.draws) > n, {}, before);
      await page.screenshot({ path: `${outDir}/${file}` });
      console.log(`screenshot: ${outDir}/${file}`);
    };
    await show(showcaseView || '', 0, 'web_viewer.png');
    await show(showcaseView || '', 2, 'web_viewer_difference.png');
  }
} finally {
  await browser.close();
}
