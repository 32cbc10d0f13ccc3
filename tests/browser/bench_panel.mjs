// Click-to-command-packet latency of the command panel (scripts/bench panel).
//   node bench_panel.mjs --url http://127.0.0.1:PORT/ --robot 127.0.0.2 --port P --clicks N
// This process stands in for the robot: it owns the robot's command port (UDP) where the bridge
// sends the 11-byte packet. Each sample: GoToPosition armed (key g, not timed), then a mouse
// click on the field in headless Chromium; timed from just before the click (including
// Playwright's input dispatch to the browser) to the packet's arrival, and to the server's reply
// at the page. Clocks: performance.timeOrigin + performance.now() in node and in the page, both
// wall-clock based with sub-millisecond resolution, on one host.
import dgram from 'node:dgram';
import { performance } from 'node:perf_hooks';
import { launch, fail, arg, until, clickField } from './lib.mjs';

const url = arg('url');
const robot = arg('robot', '127.0.0.2');
const port = Number(arg('port'));
const clicks = Number(arg('clicks', '200'));
const now = () => performance.timeOrigin + performance.now();

const sock = dgram.createSocket('udp4');
let waiting = null;
sock.on('message', (msg) => {
  const t = now();
  if (waiting) { const w = waiting; waiting = null; w({ t, msg }); }
});
await new Promise((res, rej) => { sock.once('error', rej); sock.bind(port, robot, res); });

const browser = await launch();
const rows = [];
try {
  const page = await browser.newPage({ viewport: { width: 1600, height: 1000 } });
  await page.goto(url + '#coach');
  await until('the page to connect', 10000, async () => (await page.textContent('#conn')) === 'connected');
  await until('the buttons', 5000, async () => page.locator('button[data-name="GoToPosition"]').count());
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
    const packet = new Promise((res, rej) => {
      waiting = res;
      setTimeout(() => rej(new Error(`no packet for click ${i} within 5 s`)), 5000);
    });
    const t0 = now();
    await clickField(page, x, y);
    const { t, msg } = await packet;
    if (msg.length !== 11 || msg[0] !== 1) fail(`click ${i}: unexpected packet ${msg.toString('hex')}`);
    const px = msg.readFloatLE(3), py = msg.readFloatLE(7);
    if (Math.hypot(px - x, py - y) > 60) fail(`click ${i}: packet target (${px}, ${py}) is not near (${x}, ${y})`);
    const reply = await until('the reply', 5000, async () => page.evaluate(() => window.__replies.shift()));
    if (i >= 5) rows.push({ packet_ms: t - t0, reply_ms: reply - t0 }); // 5 warm-up clicks
    await new Promise((r) => setTimeout(r, 20));
  }
} catch (e) {
  fail(e && e.stack ? e.stack : String(e));
} finally {
  await browser.close();
  sock.close();
}

const pct = (xs, p) => { const s = xs.slice().sort((a, b) => a - b); return s[Math.min(s.length - 1, Math.floor((p / 100) * s.length))]; };
const packet = rows.map((r) => r.packet_ms), reply = rows.map((r) => r.reply_ms);
const f = (v) => v.toFixed(2).padStart(8);
console.log(`\ncommand panel: ${rows.length} clicks (after 5 warm-up), GoToPosition + field click`);
console.log('| path                                   |   p50 ms |   p99 ms |   max ms |');
console.log('|----------------------------------------|---------:|---------:|---------:|');
console.log(`| click -> command packet at the robot   | ${f(pct(packet, 50))} | ${f(pct(packet, 99))} | ${f(Math.max(...packet))} |`);
console.log(`| click -> server's reply at the page    | ${f(pct(reply, 50))} | ${f(pct(reply, 99))} | ${f(Math.max(...reply))} |`);
console.log(JSON.stringify({
  clicks: rows.length,
  click_to_packet_p50_ms: pct(packet, 50),
  click_to_packet_p99_ms: pct(packet, 99),
  click_to_packet_max_ms: Math.max(...packet),
  click_to_reply_p50_ms: pct(reply, 50),
  click_to_reply_p99_ms: pct(reply, 99),
}));
