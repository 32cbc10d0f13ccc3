// The command panel end to end in headless Chromium, against a running graph (the Rust test
// tests/tests/panel.rs starts it and checks the robot's side):
//   node panel.mjs --url http://127.0.0.1:PORT/ --out DIR --target-x -2000 --target-y -1500
// Steps (each printed as `PANEL <step> <json>`): robots move on the page; the coach machine's
// status shows its state and a ball last-seen age that updates; GoToPosition + a click on the
// field is sent (the page's target is printed for the robot-side check) and the coach status
// shows it as the last command; the spoken answer appears; a click off the carpet is refused
// with its reason; bad input over a raw WebSocket is refused and the server keeps serving; a
// status that stops updating is greyed out; the talk key (V, the button, a page that goes while
// holding it); where the recognizer listens; screenshots of both views.
import { launch, report, fail, arg, until, clickField } from './lib.mjs';

const url = arg('url');
const out = arg('out');
const tx = Number(arg('target-x', '-2000'));
const ty = Number(arg('target-y', '-1500'));

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 1600, height: 1000 } });
  const consoleErrors = [];
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });
  page.on('pageerror', (e) => consoleErrors.push(String(e)));
  await page.goto(url + '#coach');
  await until('the page to connect', 10000, async () => (await page.textContent('#conn')) === 'connected');
  await until('the buttons', 5000, async () => page.locator('button[data-name="GoToPosition"]').count());

  // 1. The robots move on the page: positions change between two reads.
  const robots = async () => page.$$eval('#robots tbody tr', (rows) =>
    rows.map((r) => ({ player: Number(r.dataset.player), x: Number(r.dataset.x), y: Number(r.dataset.y) })));
  const first = await until('robots on the page', 15000, async () => { const r = await robots(); return r.length >= 2 && r; });
  let moved;
  await until('a robot to move on the page', 10000, async () => {
    const now = await robots();
    moved = now.find((r) => {
      const f = first.find((q) => q.player === r.player);
      return f && Math.hypot(r.x - f.x, r.y - f.y) > 20;
    });
    return moved;
  });
  const f = first.find((q) => q.player === moved.player);
  report('robots_moving', { player: moved.player, from: [f.x, f.y], to: [moved.x, moved.y] });
  await until('the game to be PLAYING', 20000, async () => (await page.textContent('#game-state')).startsWith('PLAYING'));
  report('game_state', { state: await page.textContent('#game-state'), time: await page.textContent('#time-left'),
    score: await page.textContent('#score'), link: await page.textContent('#link') });

  // 1b. The coach machine's status (coach/status): its state, live, and the ball's last-seen age
  // updating from new statuses (the Executive's sequence number advances), not only counted
  // on the page.
  const coach = async () => page.evaluate(() => {
    const b = document.getElementById('coach-status');
    const t = (id) => document.getElementById(id).textContent;
    return { stale: b.dataset.stale, seq: Number(b.dataset.seq), ball: b.dataset.ballAge,
      state: t('cs-state'), link: t('cs-link'), last: t('cs-last'), pending: t('cs-pending'), obstacles: t('cs-obst') };
  });
  const cs0 = await until('the coach status', 15000, async () => {
    const c = await coach();
    return c.stale === 'false' && c.state.startsWith('coach/') && c.ball !== '' && c;
  });
  const ages = new Set([cs0.ball]);
  const cs1 = await until('the ball age to update from new statuses', 10000, async () => {
    const c = await coach();
    if (c.stale === 'false' && c.ball !== '') ages.add(c.ball);
    return c.seq >= cs0.seq + 2 && ages.size >= 3 && c;
  });
  if (!cs1.state.includes('coach/playing')) fail(`the coach machine is not playing: ${cs1.state}`);
  if (!(Number(cs1.ball) >= 0 && Number(cs1.ball) < 10)) fail(`the ball was not seen lately: ${JSON.stringify(cs1)}`);
  report('coach_status', { first: cs0, later: cs1, ball_ages_shown: [...ages] });

  // 2. GoToPosition, then a click on the field.
  await page.click('button[data-name="GoToPosition"]');
  await clickField(page, tx, ty);
  await until('GoToPosition to be sent', 5000, async () => (await page.textContent('#notice')).startsWith('sent: GoToPosition'));
  const target = await page.evaluate(() => window.panel.state.target);
  if (!target || Math.hypot(target.x_mm - tx, target.y_mm - ty) > 60) fail(`the page's target ${JSON.stringify(target)} is not near (${tx}, ${ty})`);
  report('clicked', { target, sent_at_ms: Date.now() });
  const accepted = await until('an accepted history entry', 5000, async () =>
    page.$eval('#history li', (li) => li.dataset.status === 'accepted' && li.textContent));
  report('history', { first: accepted });

  // The coach machine's status names it as the last command sent.
  const last = await until('GoToPosition as the last command in the coach status', 10000, async () => {
    const c = await coach();
    return c.last.startsWith(`GoToPosition (${Math.round(target.x_mm)}, ${Math.round(target.y_mm)}) mm`) && c;
  });
  report('coach_last', { last: last.last, pending: last.pending, state: last.state });

  // 3. The spoken answer appears (speech/say).
  const said = await until('the spoken answer', 15000, async () => page.$eval('#said', (ol) => ol.textContent.trim()));
  report('said', { text: said });
  await page.waitForTimeout(1500); // let the robot walk a little for the screenshot
  await page.screenshot({ path: `${out}/panel-coach.png` });
  report('screenshot', { file: `${out}/panel-coach.png` });

  // 4. A click off the carpet (keyboard shortcut g, then the dark margin): refused, reason shown.
  await page.keyboard.press('g');
  await clickField(page, 5400, 0);
  const reason = await until('the refusal', 5000, async () => {
    const n = await page.textContent('#notice');
    return n.startsWith('refused:') && n;
  });
  if (!reason.includes('outside the field')) fail(`unexpected refusal: ${reason}`);
  await until('the refusal in the history', 5000, async () =>
    page.$eval('#history li', (li) => li.dataset.status === 'refused' && li.textContent.includes('outside the field')));
  report('refused_target', { notice: reason });

  // 5. Raw WebSocket abuse from the page's origin: each refused with a reason; a message over the
  // transport's limit closes that socket; a new socket is served.
  const raw = await page.evaluate(async () => {
    const open = () => new Promise((res, rej) => {
      const ws = new WebSocket(`ws://${location.host}/ws${location.search}`);
      ws.onopen = () => res(ws);
      ws.onerror = () => rej(new Error('cannot open'));
    });
    const reply = (ws, text) => new Promise((res) => {
      const on = (ev) => {
        if (typeof ev.data !== 'string') return;
        const m = JSON.parse(ev.data);
        if (m.type === 'reply') { ws.removeEventListener('message', on); res(m); }
      };
      ws.addEventListener('message', on);
      ws.send(text);
    });
    const ws = await open();
    const results = {};
    results.malformed = await reply(ws, '{"type": "command", "game": ');
    results.unknown = await reply(ws, '{"id": 77, "type": "command", "game": "coach", "command": "Fly"}');
    results.huge = await reply(ws, JSON.stringify({ id: 78, type: 'answer', yes: true, pad: 'x'.repeat(100000) }));
    results.closed = await new Promise((res) => {
      ws.onclose = (ev) => res({ code: ev.code });
      ws.send('z'.repeat(2 * 1024 * 1024));
      setTimeout(() => res({ code: -1 }), 5000);
    });
    const again = await open();
    results.after = await reply(again, '{"id": 79, "type": "command", "game": "coach", "command": "LookLeft"}');
    again.close();
    return results;
  });
  const why = (r) => r.entry && r.entry.reason;
  if (raw.malformed.ok || !why(raw.malformed).startsWith('malformed message')) fail(`malformed: ${JSON.stringify(raw.malformed)}`);
  if (raw.unknown.ok || why(raw.unknown) !== 'unknown command "Fly"' || raw.unknown.id !== 77) fail(`unknown: ${JSON.stringify(raw.unknown)}`);
  if (raw.huge.ok || !why(raw.huge).startsWith('message too large')) fail(`huge: ${JSON.stringify(raw.huge)}`);
  if (raw.closed.code === -1) fail('a 2 MiB message did not close its connection');
  if (!raw.after.ok) fail(`the server stopped serving: ${JSON.stringify(raw.after)}`);
  report('raw_websocket', { malformed: why(raw.malformed), unknown: why(raw.unknown), huge: why(raw.huge),
    closed_code: raw.closed.code, after: raw.after.entry.label });
  // The page itself is still connected and the refusals are in its history.
  const refusals = await page.$$eval('#history li[data-status="refused"]', (l) => l.length);
  if (refusals < 4) fail(`expected at least 4 refused entries in the history, got ${refusals}`);

  // 5a. Push-to-talk: V held, then the button held, send the talk key down, again every 0.5 s
  // while held, and up; a raw socket that holds the key and goes away has it let up by the
  // server (the Rust side checks what reached speech/talk).
  const talkHeld = async () => page.$eval('#talk', (b) => b.classList.contains('held'));
  await page.keyboard.down('v');
  await until('the talk button to show the key held', 2000, talkHeld);
  await page.waitForTimeout(1300); // a command's length
  await page.keyboard.up('v');
  await until('the talk key up', 2000, async () => !(await talkHeld()));
  const box = await page.locator('#talk').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await until('the talk button held', 2000, talkHeld);
  await page.waitForTimeout(1300);
  await page.mouse.up();
  await until('the talk button up', 2000, async () => !(await talkHeld()));
  const rawTalk = await page.evaluate(async () => {
    const ws = await new Promise((res, rej) => {
      const w = new WebSocket(`ws://${location.host}/ws${location.search}`);
      w.onopen = () => res(w);
      w.onerror = () => rej(new Error('cannot open'));
    });
    const r = await new Promise((res) => {
      ws.addEventListener('message', (ev) => {
        if (typeof ev.data !== 'string') return;
        const m = JSON.parse(ev.data);
        if (m.type === 'reply') res(m);
      });
      ws.send('{"id": 90, "type": "talk", "held": true}');
    });
    ws.close();
    return r;
  });
  if (!rawTalk.ok || rawTalk.id !== 90) fail(`the raw talk key: ${JSON.stringify(rawTalk)}`);
  const talks = await until('the talk key six times in the history', 5000, async () => {
    const l = await page.$$eval('#history li', (li) => li.map((x) => x.textContent));
    const t = l.filter((x) => x.includes('talk key'));
    return t.length >= 6 && t;
  });
  report('talk', { history: talks });

  // 5b. Stale status is greyed out: move the page's estimate of the panel's clock 10 s ahead, as
  // if coach/status had stopped arriving 10 s ago (the next render uses it), then put it back.
  await page.evaluate(() => { window.panel.state.clockOffsetMs -= 10000; });
  const stale = await until('the coach status to grey out', 3000, async () => {
    const c = await coach();
    const fresh = await page.textContent('#cs-fresh');
    const opacity = await page.$eval('#coach-status dl', (d) => Number(getComputedStyle(d).opacity));
    return c.stale === 'true' && opacity < 0.6 && fresh.startsWith('no coach/status for') && { fresh, opacity };
  });
  await page.evaluate(() => { window.panel.state.clockOffsetMs += 10000; });
  await until('the coach status to be live again', 3000, async () => (await coach()).stale === 'false');
  report('coach_stale', stale);

  // 6. The touch view (camera, ball window, dialog), by its shortcut.
  await page.keyboard.press('2');
  await until('the touch view', 3000, async () => page.isVisible('#view-touch'));
  const camera = await until('a camera image', 15000, async () =>
    page.$eval('#camera', (img) => img.naturalWidth > 0 && { width: img.naturalWidth, height: img.naturalHeight }));
  const ball = await until('a ball track', 10000, async () => {
    const t = await page.textContent('#ball-info');
    return t.startsWith('tracking') && t.includes('window') && t;
  });
  // Where the recognizer listens (the Rust side publishes speech/listening: a talker at 60
  // degrees to the left, someone else's).
  const hearing = await until('the hearing line', 5000, async () => {
    const t = await page.textContent('#hearing');
    return t.includes('listening to player at 0° (ahead)') && t.includes('a sound from 60°, someone else') && t;
  });
  report('touch', { camera, ball, hearing });
  await page.click('button[data-name="TouchBall"]');
  await until('TouchBall to be sent', 5000, async () => (await page.textContent('#notice')).startsWith('sent: TouchBall'));
  await page.keyboard.press('y');
  await until('the yes answer to be sent', 5000, async () => (await page.textContent('#notice')).startsWith('sent: answer: yes'));
  await page.waitForTimeout(500);
  await page.screenshot({ path: `${out}/panel-touch.png` });
  report('screenshot', { file: `${out}/panel-touch.png` });

  if (consoleErrors.length) fail(`errors in the page's console: ${consoleErrors.join(' | ')}`);
  report('done');
} catch (e) {
  fail(e && e.stack ? e.stack : String(e));
} finally {
  await browser.close();
}
