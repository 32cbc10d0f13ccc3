// Shared by the browser scripts: start the system's Chromium headless through playwright-core,
// print results as `PANEL <step> <json>` lines (the Rust test reads them), fail loudly.
import { chromium } from 'playwright-core';
import { existsSync } from 'node:fs';

export function chromiumPath() {
  const candidates = [process.env.CHROMIUM, '/usr/bin/chromium', '/usr/bin/chromium-browser'].filter(Boolean);
  const found = candidates.find((p) => existsSync(p));
  if (!found) {
    fail(`no Chromium found (tried ${candidates.join(', ')}): run scripts/test, which installs it`);
  }
  return found;
}

export async function launch() {
  return chromium.launch({
    executablePath: chromiumPath(),
    headless: true,
    // Root in a container has no user namespaces for the sandbox; the page is our own.
    args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'],
  });
}

export function report(step, data = {}) {
  console.log(`PANEL ${step} ${JSON.stringify(data)}`);
}

export function fail(message) {
  console.error(`FAILED: ${message}`);
  process.exit(1);
}

export function arg(name, fallback) {
  const i = process.argv.indexOf(`--${name}`);
  if (i >= 0 && i + 1 < process.argv.length) return process.argv[i + 1];
  if (fallback === undefined) fail(`missing --${name}`);
  return fallback;
}

/// Wait until `fn()` returns a truthy value (polled), else fail naming `what`.
export async function until(what, timeoutMs, fn, everyMs = 100) {
  const end = Date.now() + timeoutMs;
  let last;
  while (Date.now() < end) {
    try {
      last = await fn();
      if (last) return last;
    } catch (e) {
      last = e;
    }
    await new Promise((r) => setTimeout(r, everyMs));
  }
  fail(`timed out after ${timeoutMs} ms waiting for ${what} (last: ${last})`);
}

/// Click the field canvas at field point (x, y) mm, as a person would.
export async function clickField(page, x, y) {
  const p = await page.evaluate(([fx, fy]) => {
    const cv = document.getElementById('field');
    const r = cv.getBoundingClientRect();
    const [px, py] = window.panel.fieldToCanvas(fx, fy);
    return { x: r.left + px * (r.width / cv.width), y: r.top + py * (r.height / cv.height) };
  }, [x, y]);
  await page.mouse.click(p.x, p.y);
}
