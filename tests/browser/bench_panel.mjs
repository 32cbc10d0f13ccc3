// Click-to-command latency of the command panel (scripts/bench panel).
//   node bench_panel.mjs --url http://127.0.0.1:PORT/ --echo "robocog topic echo nao/command ..." --clicks N
// The panel sends a coach request; the Executive's coach machine checks it against the game
// state and the world model, answers it and publishes the command on `nao/command`, which the
// bridge turns into the robot's UDP packet (that last hop is `scripts/bench coach`'s). Each
// sample: GoToPosition armed (key g, not timed), then a mouse click on the field in headless
// Chromium; timed from just before the click (including Playwright's input dispatch to the
// browser) to the checked command's stamp on `nao/command` (the Executive stamps it with the
// system clock as it publishes; read with `robocog topic echo`), and to the server's reply at the
// page. Clocks: performance.timeOrigin + performance.now() in node and in the page, and the
// publisher's system clock: all wall-clock, on one host.
import { spawn } from 'node:child_process';
import readline from 'node:readline';
import { performance } from 'node:perf_hooks';
import { launch, fail, arg, until, clickField } from './lib.mjs';

const url = arg('url');
const echoCmd = JSON.parse(arg('echo')); // [program, ...args]
const clicks = Number(arg('clicks', '200'));
const now = () => performance.timeOrigin + performance.now();

// Every nao/command as JSON, one per line.
const echo = spawn(echoCmd[0], echoCmd.slice(1), { stdio: ['ignore', 'pipe', 'inherit'] });
let waiting = null;
readline.createInterface({ input: echo.stdout }).on('line', (line) => {
  let m;
  try { m = JSON.parse(line); } catch { return; }
  const c = m.body !== undefined ? m : m.message || m.msg || m;
  if (c.body !== 'GoToPosition' || !c.header) return;
  const t = Number(c.header.stamp_ns) / 1e6;
  if (waiting) { const w = waiting; waiting = null; w({ t, c }); }
});

const browser = await launch();
const rows = [];
try {
  const page = await browser.newPage({ viewport: { width: 1600, height: 1000 } });
  await page.goto(url + '#coach');
  await until('the page to connect', 10000, async () => (await page.textContent('#conn')) === 'connected');
  await until('the buttons', 5000, async () => page.locator('button[data-name="GoToPosition"]').count());
  // The coach machine moves the robot only in PLAYING.
  await until('the game to be PLAYING', 60000, async () => (await page.textContent('#game-state')).startsWith('PLAYING'));
  await page.evaluate(() => {
    window.__replies = [];
    const ws = window.panel.state.ws;
    ws.addEventListener('message', (ev) => {
      const t = performance.timeOrigin + performance.now();
      if (typeof ev.data === 'string' && ev.data.includes('"type":"reply"')) window.__replies.push(t);
    });
  });
  const targets = [[-3000, 1500], [2500, -1200], [0, 2000], [-1000, -2500]];
  for (let i = 0; i < clicks + 5; i++) {
    const [x, y] = targets[i % targets.length];
    await page.keyboard.press('g');
    // The coach moves the robot in PLAYING only: a click outside it is refused, so say so.
    const state = await page.textContent('#game-state');
    if (!state.startsWith('PLAYING')) fail(`click ${i}: the game left PLAYING (${state}); the bench needs a longer attack`);
    const packet = new Promise((res, rej) => {
      waiting = res;
      setTimeout(() => rej(new Error(`no checked command on nao/command for click ${i} within 5 s (game state ${state})`)), 5000);
    });
    const t0 = now();
    await clickField(page, x, y);
    const { t, c } = await packet;
    const px = c.target.x_mm, py = c.target.y_mm;
    if (Math.hypot(px - x, py - y) > 60) fail(`click ${i}: command target (${px}, ${py}) is not near (${x}, ${y})`);
    const reply = await until('the reply', 5000, async () => page.evaluate(() => window.__replies.shift()));
    if (i >= 5) rows.push({ packet_ms: t - t0, reply_ms: reply - t0 }); // 5 warm-up clicks
    await new Promise((r) => setTimeout(r, 20));
  }
} catch (e) {
  fail(e && e.stack ? e.stack : String(e));
} finally {
  await browser.close();
  echo.kill();
}

const pct = (xs, p) => { const s = xs.slice().sort((a, b) => a - b); return s[Math.min(s.length - 1, Math.floor((p / 100) * s.length))]; };
const packet = rows.map((r) => r.packet_ms), reply = rows.map((r) => r.reply_ms);
const f = (v) => v.toFixed(2).padStart(8);
console.log(`\ncommand panel: ${rows.length} clicks (after 5 warm-up), GoToPosition + field click`);
console.log('| path                                   |   p50 ms |   p99 ms |   max ms |');
console.log('|----------------------------------------|---------:|---------:|---------:|');
console.log(`| click -> checked command (nao/command) | ${f(pct(packet, 50))} | ${f(pct(packet, 99))} | ${f(Math.max(...packet))} |`);
console.log(`| click -> server's reply at the page    | ${f(pct(reply, 50))} | ${f(pct(reply, 99))} | ${f(Math.max(...reply))} |`);
console.log(JSON.stringify({
  clicks: rows.length,
  click_to_command_p50_ms: pct(packet, 50),
  click_to_command_p99_ms: pct(packet, 99),
  click_to_command_max_ms: Math.max(...packet),
  click_to_reply_p50_ms: pct(reply, 50),
  click_to_reply_p99_ms: pct(reply, 99),
}));
