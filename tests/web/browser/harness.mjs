// What the browser tests (console_test.mjs, viewer_test.mjs) share: Debian's headless chromium launched through the
// pinned puppeteer-core, every console error and uncaught page error collected into seen.consoleErrors, and the
// run's end: one JSON line of what the test saw, then a non-zero exit with the reason on a failure.
import puppeteer from 'puppeteer-core';

// Runs `body(page)` on a new page of chromium (`args` added to the common flags). `seen` is the object printed at the
// end; `expectedError(message, url)` true keeps an error the test provokes on purpose out of seen.consoleErrors.
export async function runInChromium({ chromium, profile, args = [], timeoutMs, seen, expectedError = () => false },
                                    body) {
  seen.consoleErrors = seen.consoleErrors || [];
  const browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    userDataDir: profile,
    args: ['--no-sandbox', '--no-first-run', '--disable-dev-shm-usage', ...args],
  });
  let failed = null;
  try {
    const page = await browser.newPage();
    page.setDefaultTimeout(timeoutMs);
    page.on('console', (m) => {
      if (m.type() !== 'error') return;
      const where = (m.location() && m.location().url) || '';
      if (expectedError(m, where)) return;
      seen.consoleErrors.push(m.text() + (where ? ' (' + where + ')' : ''));
    });
    page.on('pageerror', (e) => seen.consoleErrors.push('page error: ' + e.message));
    await body(page);
  } catch (e) {
    failed = String(e && e.stack || e);
  } finally {
    await browser.close();
  }
  console.log(JSON.stringify(seen));
  if (failed) {
    console.error(failed);
    process.exit(1);
  }
}
