// The web console in a real browser (run by tests/web/test_browser.cpp): Debian's headless chromium driven by the
// pinned puppeteer-core. Opens the URL `vdrig serve` prints, starts a simulated session from the form (after one
// the daemon refuses, whose reason must show), watches progress events arrive, pauses, resumes, waits for the end,
// and fails on any console error. Prints one JSON line of what it saw; exits non-zero with the reason on a failure.
//   node console_test.mjs URL CHROMIUM PROFILE_DIR SESSION SCHEME
import { runInChromium } from './harness.mjs';

const [url, chromium, profile, session, scheme] = process.argv.slice(2);
const seen = { consoleErrors: [], expectedRefusals: 0, steps: [] };
// The one error the browser logs by design: the refused start's 400 ("Failed to load resource"), while it is awaited.
let refusalAwaited = false;
const step = (s) => seen.steps.push(s);
const expectedError = (m, where) => {
  if (!(refusalAwaited && where.endsWith('/api/start') && m.text().includes('status of 400'))) return false;
  seen.expectedRefusals += 1;
  return true;
};

const options = { chromium, profile, args: ['--disable-gpu'], timeoutMs: 15000, seen, expectedError };
await runInChromium(options, async (page) => {
  const text = (sel) => page.$eval(sel, (el) => el.textContent);
  const progress = () => page.$eval('#progress', (el) => [el.value, el.max]);

  await page.goto(url, { waitUntil: 'domcontentloaded' });
  seen.address = page.url();  // the token went into a cookie, out of the address
  await page.waitForSelector('#daemon.up');
  step('daemon connected');

  const fill = async (name, value) => page.$eval(`input[name="${name}"]`, (el, v) => { el.value = v; }, value);
  // The daemon's own validation, relayed: a scheme it does not know.
  await fill('session', session);
  await fill('scheme', 'nonsense:3');
  await fill('bracket', 'fixed:0.01,0.02');
  await fill('scene', 'patchwork');
  refusalAwaited = true;
  await page.click('#start-form button[type="submit"]');
  await page.waitForFunction(() => document.getElementById('start-error').textContent.length > 0);
  refusalAwaited = false;
  seen.startError = await text('#start-error');
  step('bad scheme refused');

  await fill('scheme', scheme);
  const before = Number(await text('#event-count'));
  await page.click('#start-form button[type="submit"]');
  await page.waitForFunction(() => document.getElementById('state').textContent === 'running' &&
                             Number(document.getElementById('progress').value) >= 1);
  step('running');
  await page.click('#pause');
  await page.waitForFunction(() => document.getElementById('state').textContent === 'paused');
  seen.eventsWhileRunning = Number(await text('#event-count')) - before;
  const [pausedAt, total] = await progress();
  seen.pausedAt = pausedAt;
  seen.total = total;
  step('paused');
  await new Promise((r) => setTimeout(r, 700));
  seen.progressAfterPause = (await progress())[0];
  seen.stateAfterPause = await text('#state');

  await page.click('#resume');
  await page.waitForFunction(() => document.getElementById('state').textContent === 'completed', { timeout: 30000 });
  step('completed');
  seen.final = await progress();
  // The list follows: the session's row says every view is done.
  await page.waitForFunction((s, n) => {
    const row = document.querySelector(`tr[data-session="${s}"]`);
    return row && row.children[1].textContent === `${n}/${n}`;
  }, {}, session, total);
  seen.row = await page.$eval(`tr[data-session="${session}"]`, (el) => el.children[1].textContent);
  step('listed');
  seen.events = Number(await text('#event-count'));

  // The live pieces: the hemisphere filled in, the last frame's thumbnail with its bracket and saturation, the
  // journal's tail.
  await page.waitForFunction((n) => document.getElementById('hemisphere').dataset.done === String(n), {}, total);
  seen.hemisphere = await page.$eval('#hemisphere', (c) => {
    const g = c.getContext('2d');
    const px = g.getImageData(0, 0, c.width, c.height).data;
    let green = 0;
    for (let i = 0; i < px.length; i += 4) if (px[i + 1] > 100 && px[i] < 90 && px[i + 2] < 90) green += 1;
    return { done: Number(c.dataset.done), views: Number(c.dataset.views), greenPixels: green };
  });
  // The thumbnail ends on the session's last frame: the last "view V frame B" line of the journal's tail, once that
  // view is complete (a thumbnail asked for mid-session may still be on its way: wait for it, do not sample it).
  await page.waitForFunction(() => {
    const img = document.getElementById('thumbnail');
    const log = document.getElementById('log-tail').textContent;
    const frames = [...log.matchAll(/view (\d+) frame (\d+)/g)];
    if (img.naturalWidth === 0 || frames.length === 0) return false;
    const [, v, b] = frames[frames.length - 1];
    return log.trimEnd().endsWith(`view ${v} complete`) && img.dataset.view === v && img.dataset.bracket === b;
  });
  seen.thumbnail = await page.$eval('#thumbnail', (img) => {
    const c = document.createElement('canvas');
    c.width = img.naturalWidth;
    c.height = img.naturalHeight;
    const g = c.getContext('2d');
    g.drawImage(img, 0, 0);
    const px = g.getImageData(0, 0, c.width, c.height).data;
    let sum = 0, min = 255, max = 0;
    for (let i = 0; i < px.length; i += 4) {
      const v = (px[i] + px[i + 1] + px[i + 2]) / 3;
      sum += v; min = Math.min(min, v); max = Math.max(max, v);
    }
    return { width: img.naturalWidth, height: img.naturalHeight, view: Number(img.dataset.view),
             bracket: Number(img.dataset.bracket), saturated: Number(img.dataset.saturated),
             mean: sum / (px.length / 4), min, max };
  });
  seen.thumbnailText = await text('#thumbnail-text');
  seen.logTail = await text('#log-tail');
  seen.drive = await text('#drive-text');
  seen.camera = await text('#camera-text');
  step('live pieces');

  // Home, then jog pan by the step: the daemon's replies give the position.
  await page.click('#home');
  await page.waitForFunction(() => document.getElementById('stage-text').textContent.startsWith('pan '));
  seen.homed = await text('#stage-text');
  await page.$eval('#jog-step', (el) => { el.value = '7.5'; });
  await page.click('[data-jog="pan,1"]');
  await page.waitForFunction((h) => document.getElementById('stage-text').textContent.startsWith('pan ') &&
                             document.getElementById('stage-text').textContent !== h, {}, seen.homed);
  seen.jogged = await text('#stage-text');
  step('homed and jogged');
});
