// The command panel's page: one WebSocket to the server (see the crate docs for its messages),
// the coach's field on a canvas, the touch game's camera, buttons built from the server's catalog.
// Field frame: mm, origin at the centre spot, x towards the opponent goal, y to the left.
'use strict';

const MARGIN_MM = 300; // drawn beyond the carpet, so a click there is a target the server refuses
const state = {
  ws: null,
  catalog: null,
  talkTimer: null, // set while the talk key is held
  view: location.hash === '#touch' ? 'touch' : 'coach',
  nextId: 1,
  pick: null, // {kind: 'command'|'nao', name} while waiting for a field click
  target: null, // the last target sent {x_mm, y_mm}
  world: null,
  local: {}, // per player
  game: null,
  links: {}, // per player: last nao/link event
  rgbd: null,
  ball: null,
  cameraUrl: null,
  said: [],
  coach: null, // the latest coach_status message
  clockOffsetMs: 0, // this browser's clock minus the panel's (from hello)
  staleAfterMs: 3000, // from hello
};
const $ = (id) => document.getElementById(id);

// ---------- connection ----------
function connect() {
  const token = new URLSearchParams(location.search).get('token');
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws` +
    (token ? `?token=${encodeURIComponent(token)}` : '');
  const ws = new WebSocket(url);
  ws.binaryType = 'blob';
  state.ws = ws;
  ws.onopen = () => setConn(true);
  ws.onclose = () => { setConn(false); setTimeout(connect, 1000); };
  ws.onmessage = (ev) => {
    if (typeof ev.data !== 'string') { showCamera(ev.data); return; }
    let m;
    try { m = JSON.parse(ev.data); } catch (e) { console.warn('bad message from the server', e); return; }
    handle(m);
  };
}
function setConn(up) {
  const c = $('conn');
  c.textContent = up ? 'connected' : 'disconnected: retrying';
  c.className = 'conn ' + (up ? 'up' : 'down');
}
function send(obj) {
  const id = state.nextId++;
  const msg = Object.assign({ id }, obj);
  if (!state.ws || state.ws.readyState !== WebSocket.OPEN) {
    notice('not connected: the command was not sent', false);
    return 0;
  }
  state.ws.send(JSON.stringify(msg));
  return id;
}
// For tests and power users: the page's own API.
window.panel = {
  send,
  sendRaw: (text) => state.ws.send(text),
  state,
  fieldToCanvas: (x, y) => fieldToCanvas(x, y),
};

// ---------- messages ----------
function handle(m) {
  switch (m.type) {
    case 'hello':
      state.catalog = m.catalog; buildButtons();
      if (Number.isFinite(m.server_time_ms)) state.clockOffsetMs = Date.now() - m.server_time_ms;
      if (Number.isFinite(m.stale_after_ms)) state.staleAfterMs = m.stale_after_ms;
      break;
    case 'coach_status': state.coach = m; renderCoach(); break;
    case 'reply': onReply(m); break;
    case 'history': renderHistory(m.entries); break;
    case 'state': onState(m.topic, m.data); break;
    case 'event': onEvent(m.topic, m.data); break;
    default: console.warn('unknown message', m.type);
  }
}
function onReply(m) {
  const e = m.entry;
  if (e && e.label.startsWith('talk key')) {
    if (!m.ok) notice(`the talk key was not sent: ${e.reason || 'the panel is busy'}`, false);
    return;
  }
  if (m.ok) {
    notice(`${e.status === 'pending' ? 'next command will carry' : 'sent'}: ${e.label}`, true);
    if (e.target) { state.target = e.target; drawField(); }
  } else {
    notice(`refused: ${e.reason}`, false);
  }
}
function onState(topic, d) {
  switch (topic) {
    case 'nao/world_model': state.world = d; renderRobots(); drawField(); break;
    case 'nao/local_model': state.local[d.player_number] = d; renderStatus(); drawField(); break;
    case 'nao/game_state': state.game = d; renderStatus(); renderRobots(); break;
    case 'vision/rgbd': state.rgbdNext = d; break; // describes the image that follows
    case 'vision/ball': state.ball = d; renderBall(); break;
    case 'executive/transitions': renderExec(d); break;
    case 'speech/listening': renderHearing(d); break;
  }
}
// Where the recognizer's beam listens and where it hears sound from (degrees, the array's frame:
// 0 straight ahead, positive to the left).
function renderHearing(d) {
  const deg = (r) => `${Math.round(r * 180 / Math.PI)}°`;
  const side = (r) => Math.abs(r) < 0.05 ? 'ahead' : r > 0 ? 'left' : 'right';
  // What the beam is steered at: a node of the deep representation, or the loudest talker.
  const to = d.listening_to && d.listening_to !== 'fixed' ? ` to ${d.listening_to}` : '';
  let t = `${d.header.frame_id}: listening${to} at ${deg(d.beam_azimuth_rad)} (${side(d.beam_azimuth_rad)})`;
  if (d.located) t += `; a sound from ${deg(d.talker_azimuth_rad)}${d.elsewhere ? ', someone else' : ', her'}`;
  $('hearing').textContent = t;
  $('hearing').dataset.elsewhere = String(d.located && d.elsewhere);
}
function onEvent(topic, d) {
  switch (topic) {
    case 'speech/say':
      addLog('said', d.text, 'say');
      addLog('dialog', `robot: ${d.text}`, 'say');
      break;
    case 'speech/utterance':
      addLog('dialog', `heard: "${d.text || '(nothing)'}" (confidence ${d.confidence.toFixed(2)}` +
        `${d.in_grammar ? '' : ', not a command'})`, 'heard');
      break;
    case 'game/command':
      if (d.source === 'Voice') addLog('dialog', `command: ${d.command} (voice${d.confirmed ? ', confirmed' : ''})`, 'cmd');
      break;
    case 'executive/log': addLog('game-log', `[${d.kind}] ${d.text}`, d.kind); break;
    case 'vision/ball_events': addLog('game-log', `[ball] ${d.kind}`, 'ball'); break;
    case 'nao/link': state.links[d.player_number] = d; renderStatus(); break;
    case 'panel/delivery':
      // A command held while the component that acts on it restarts: held, sent, or dropped.
      addLog('game-log', `[panel] ${d.what} on ${d.topic}: ${d.state}, ${d.detail}`,
        d.state === 'dropped' ? 'anomaly' : 'cmd');
      if (d.state !== 'sent') notice(`${d.what}: ${d.state}, ${d.detail}`, d.state === 'held');
      break;
  }
}

// ---------- buttons and keys ----------
function button(parent, label, key, onClick, extraClass) {
  const b = document.createElement('button');
  b.textContent = label;
  b.dataset.name = label;
  if (extraClass) b.className = extraClass;
  if (key) {
    const k = document.createElement('kbd');
    k.textContent = keyLabel(key);
    b.appendChild(k);
    b.title = `shortcut: ${keyLabel(key)}`;
  }
  b.addEventListener('click', onClick);
  parent.appendChild(b);
  return b;
}
function keyLabel(k) {
  return { ' ': 'Space', ArrowLeft: '←', ArrowRight: '→', ArrowUp: '↑', ArrowDown: '↓' }[k] || k;
}
const keymap = { coach: {}, touch: {} };
function buildButtons() {
  const c = state.catalog;
  for (const id of ['coach-body', 'coach-head', 'coach-strategy', 'coach-answer', 'touch-commands', 'touch-answer']) $(id).textContent = '';
  keymap.coach = {}; keymap.touch = {};
  const heads = new Set(['LookLeft', 'LookRight', 'LookAtBall']);
  for (const cmd of c.coach) {
    const parent = cmd.answer ? $('coach-answer') : heads.has(cmd.name) ? $('coach-head') : $('coach-body');
    const act = () => coachCommand(cmd);
    button(parent, cmd.name, cmd.shortcut, act, cmd.name === 'Stop' ? 'stop' : '');
    if (cmd.shortcut) keymap.coach[cmd.shortcut] = { label: cmd.name, act };
  }
  for (const b of c.nao_bodies) {
    const act = () => b.needs_target ? armPick({ kind: 'nao', name: b.name }) : send({ type: 'nao', body: b.name });
    button($('coach-body'), b.name, b.shortcut, act, 'nao');
    if (b.shortcut) keymap.coach[b.shortcut] = { label: b.name, act };
  }
  for (const h of c.nao_heads) {
    const act = () => send({ type: 'nao', head: h.name });
    button($('coach-head'), h.name, h.shortcut, act, 'nao');
    if (h.shortcut) keymap.coach[h.shortcut] = { label: h.name, act };
  }
  for (const s of c.strategies) button($('coach-strategy'), s, null, () => send({ type: 'strategy', strategy: s }));
  for (const cmd of c.touch) {
    const parent = cmd.answer ? $('touch-answer') : $('touch-commands');
    const act = () => cmd.answer ? send({ type: 'answer', yes: cmd.name === 'Yes' })
      : send({ type: 'command', game: 'touch', command: cmd.name });
    button(parent, cmd.name, cmd.shortcut, act, cmd.name === 'Stop' ? 'stop' : '');
    if (cmd.shortcut) keymap.touch[cmd.shortcut] = { label: cmd.name, act };
  }
  const tb = $('shortcuts').tBodies[0];
  tb.textContent = '';
  if (c.talk && c.talk.shortcut) TALK_KEY = c.talk.shortcut;
  const talkRow = tb.insertRow();
  talkRow.insertCell().innerHTML = `<kbd>${keyLabel(TALK_KEY)}</kbd> held`;
  talkRow.insertCell().textContent = 'talk (push-to-talk)';
  talkRow.insertCell().textContent = 'both';
  for (const view of ['coach', 'touch']) {
    for (const [k, v] of Object.entries(keymap[view])) {
      const tr = tb.insertRow();
      tr.insertCell().innerHTML = `<kbd>${keyLabel(k)}</kbd>`;
      tr.insertCell().textContent = v.label;
      tr.insertCell().textContent = view;
    }
  }
}
function coachCommand(cmd) {
  if (cmd.answer) send({ type: 'answer', yes: cmd.name === 'Yes' });
  else if (cmd.needs_target) armPick({ kind: 'command', name: cmd.name });
  else send({ type: 'command', game: 'coach', command: cmd.name });
}
function armPick(p) {
  state.pick = p;
  const h = $('pick-hint');
  h.hidden = false;
  h.textContent = `${p.name}: click the target on the field (Esc cancels)`;
  $('field').classList.add('picking');
}
function cancelPick() {
  state.pick = null;
  $('pick-hint').hidden = true;
  $('field').classList.remove('picking');
}
// ---------- push-to-talk ----------
// Held: {type: 'talk', held: true} at once and every TALK_REPEAT_MS, so a recognizer in
// push-to-talk mode hears the operator; released (button up, key up, the page hidden or left):
// held false. A page that stops sending (hung, closed) is taken as released by the recognizer.
const TALK_REPEAT_MS = 500;
let TALK_KEY = 'v'; // the catalog's talk shortcut
function talk(held) {
  if (held === !!state.talkTimer) return;
  if (held) {
    send({ type: 'talk', held: true });
    state.talkTimer = setInterval(() => send({ type: 'talk', held: true }), TALK_REPEAT_MS);
  } else {
    clearInterval(state.talkTimer);
    state.talkTimer = null;
    send({ type: 'talk', held: false });
  }
  $('talk').classList.toggle('held', held);
  $('talk').setAttribute('aria-pressed', String(held));
}
$('talk').addEventListener('pointerdown', (ev) => { ev.preventDefault(); $('talk').setPointerCapture(ev.pointerId); talk(true); });
for (const e of ['pointerup', 'pointercancel', 'lostpointercapture']) $('talk').addEventListener(e, () => talk(false));
window.addEventListener('blur', () => talk(false));
document.addEventListener('visibilitychange', () => { if (document.hidden) talk(false); });
document.addEventListener('keyup', (ev) => { if (ev.key.toLowerCase() === TALK_KEY) talk(false); });

document.addEventListener('keydown', (ev) => {
  if (ev.target instanceof HTMLInputElement || ev.ctrlKey || ev.metaKey || ev.altKey) return;
  if (ev.key.toLowerCase() === TALK_KEY) { ev.preventDefault(); if (!ev.repeat) talk(true); return; }
  if (ev.key === 'Escape') { cancelPick(); return; }
  if (ev.key === '1') { setView('coach'); return; }
  if (ev.key === '2') { setView('touch'); return; }
  if (ev.key === '?') { $('help').open = !$('help').open; return; }
  const k = keymap[state.view][ev.key] || keymap[state.view][ev.key.toLowerCase()];
  if (k) { ev.preventDefault(); k.act(); }
});
function setView(v) {
  state.view = v;
  $('view-coach').hidden = v !== 'coach';
  $('view-touch').hidden = v !== 'touch';
  $('tab-coach').classList.toggle('active', v === 'coach');
  $('tab-touch').classList.toggle('active', v === 'touch');
  history.replaceState(null, '', `${location.search}#${v}`);
  drawField();
}
for (const t of document.querySelectorAll('.tab')) t.addEventListener('click', () => setView(t.dataset.view));

// ---------- the field ----------
function dims() {
  const f = (state.catalog && state.catalog.field) || { half_length_mm: 4500, half_width_mm: 3000, border_mm: 700 };
  const hx = f.half_length_mm + f.border_mm + MARGIN_MM;
  const hy = f.half_width_mm + f.border_mm + MARGIN_MM;
  return { f, hx, hy };
}
function fieldToCanvas(x, y) {
  const cv = $('field');
  const { hx, hy } = dims();
  const s = cv.width / (2 * hx);
  return [(x + hx) * s, (hy - y) * s, s];
}
function canvasToField(px, py) {
  const cv = $('field');
  const { hx, hy } = dims();
  const s = cv.width / (2 * hx);
  return [px / s - hx, hy - py / s];
}
$('field').addEventListener('click', (ev) => {
  const cv = $('field');
  const r = cv.getBoundingClientRect();
  const px = (ev.clientX - r.left) * (cv.width / r.width);
  const py = (ev.clientY - r.top) * (cv.height / r.height);
  const [x, y] = canvasToField(px, py);
  const target = { x_mm: Math.round(x), y_mm: Math.round(y) };
  if (!state.pick) { notice(`(${target.x_mm}, ${target.y_mm}) mm: press GoToPosition or Turn first`, true); return; }
  const p = state.pick;
  cancelPick();
  if (p.kind === 'command') send({ type: 'command', game: 'coach', command: p.name, target });
  else send({ type: 'nao', body: p.name, target });
});

function drawField() {
  if (state.view !== 'coach') return;
  const cv = $('field');
  const g = cv.getContext('2d');
  const { f, hx, hy } = dims();
  const [, , s] = fieldToCanvas(0, 0);
  const P = (x, y) => fieldToCanvas(x, y);
  g.fillStyle = '#333'; g.fillRect(0, 0, cv.width, cv.height);
  const [cx0, cy0] = P(-(f.half_length_mm + f.border_mm), f.half_width_mm + f.border_mm);
  g.fillStyle = '#2e7d32';
  g.fillRect(cx0, cy0, 2 * (f.half_length_mm + f.border_mm) * s, 2 * (f.half_width_mm + f.border_mm) * s);
  g.strokeStyle = '#fff'; g.lineWidth = Math.max(1, 50 * s);
  const rect = (x0, y0, x1, y1) => { const [a, b] = P(x0, y1); g.strokeRect(a, b, (x1 - x0) * s, (y1 - y0) * s); };
  const L = f.half_length_mm, W = f.half_width_mm;
  rect(-L, -W, L, W);
  g.beginPath(); let [a, b] = P(0, W); g.moveTo(a, b); [a, b] = P(0, -W); g.lineTo(a, b); g.stroke();
  g.beginPath(); [a, b] = P(0, 0); g.arc(a, b, 750 * s, 0, 2 * Math.PI); g.stroke();
  for (const sgn of [-1, 1]) {
    rect(Math.min(sgn * L, sgn * (L - 1650)), -2000, Math.max(sgn * L, sgn * (L - 1650)), 2000); // penalty area
    rect(Math.min(sgn * L, sgn * (L - 600)), -1100, Math.max(sgn * L, sgn * (L - 600)), 1100); // goal area
    [a, b] = P(sgn * (L - 1300), 0); g.fillStyle = '#fff'; g.fillRect(a - 50 * s, b - 50 * s, 100 * s, 100 * s);
    g.strokeStyle = sgn > 0 ? '#ffd54f' : '#90caf9'; g.lineWidth = Math.max(2, 100 * s);
    rect(Math.min(sgn * L, sgn * (L + 500)), -800, Math.max(sgn * L, sgn * (L + 500)), 800); // goal
    g.strokeStyle = '#fff'; g.lineWidth = Math.max(1, 50 * s);
  }
  g.font = `${Math.max(10, 220 * s)}px sans-serif`; g.fillStyle = 'rgba(255,255,255,0.6)';
  [a, b] = P(L - 1200, -W - 450); g.fillText('opponent goal →', a, b);

  const w = state.world;
  if (w) {
    for (const o of w.obstacles) {
      const alpha = Math.max(0.12, 1 - o.age_s / 5);
      const opp = o.kind === 3 || o.kind === 6;
      g.globalAlpha = alpha;
      g.fillStyle = opp ? '#e53935' : o.kind === 0 ? '#eeeeee' : '#9e9e9e';
      [a, b] = P(o.center.x_mm, o.center.y_mm);
      g.beginPath(); g.arc(a, b, 150 * s, 0, 2 * Math.PI); g.fill();
      if (o.kind >= 5) cross(g, a, b, 150 * s);
      g.globalAlpha = 1;
    }
    for (const r of w.robots) drawRobot(g, P, s, r, w);
    if (w.ball_known) {
      const vx = w.ball_velocity.x_mm, vy = w.ball_velocity.y_mm;
      [a, b] = P(w.ball.x_mm, w.ball.y_mm);
      g.globalAlpha = Math.max(0.3, 1 - w.ball_age_s / 5);
      g.fillStyle = '#ff9800'; g.beginPath(); g.arc(a, b, 80 * s, 0, 2 * Math.PI); g.fill();
      if (Math.hypot(vx, vy) > 50) {
        const [c, d] = P(w.ball.x_mm + vx, w.ball.y_mm + vy);
        arrow(g, a, b, c, d, '#ff9800', Math.max(1.5, 30 * s));
      }
      g.globalAlpha = 1;
    }
  }
  const own = state.local[2];
  if (own && own.ball_age_s < 5) {
    [a, b] = P(own.ball.x_mm, own.ball.y_mm);
    g.strokeStyle = '#ffcc80'; g.lineWidth = 2; g.beginPath(); g.arc(a, b, 110 * s, 0, 2 * Math.PI); g.stroke();
  }
  if (state.target) {
    [a, b] = P(state.target.x_mm, state.target.y_mm);
    g.strokeStyle = '#00e5ff'; g.lineWidth = 3; cross(g, a, b, 120 * s);
    g.beginPath(); g.arc(a, b, 200 * s, 0, 2 * Math.PI); g.stroke();
  }
}
function drawRobot(g, P, s, r, w) {
  const [a, b] = P(r.pose.x_mm, r.pose.y_mm);
  const controlled = r.player_number === 2;
  const silent = r.age_s > 1.0;
  const pen = penalty(r.player_number);
  g.save();
  if (silent) { g.setLineDash([6, 4]); g.globalAlpha = 0.5; }
  g.fillStyle = pen ? '#757575' : controlled ? '#1e88e5' : '#26c6da';
  g.strokeStyle = '#000'; g.lineWidth = 2;
  g.beginPath(); g.arc(a, b, 170 * s, 0, 2 * Math.PI); g.fill(); g.stroke();
  g.setLineDash([]);
  g.strokeStyle = '#fff'; g.lineWidth = 3; g.beginPath(); g.moveTo(a, b);
  g.lineTo(a + Math.cos(r.pose.theta_rad) * 300 * s, b - Math.sin(r.pose.theta_rad) * 300 * s); g.stroke();
  if (r.fallen) { g.strokeStyle = '#ff1744'; g.lineWidth = 4; cross(g, a, b, 200 * s); }
  g.fillStyle = '#fff'; g.font = `bold ${Math.max(11, 200 * s)}px sans-serif`;
  g.fillText(`${r.player_number}${pen ? ' P' : ''} ${roleName(r, w)}`, a + 200 * s, b - 200 * s);
  g.restore();
}
function cross(g, a, b, r) {
  g.beginPath(); g.moveTo(a - r, b - r); g.lineTo(a + r, b + r); g.moveTo(a + r, b - r); g.lineTo(a - r, b + r); g.stroke();
}
function arrow(g, a, b, c, d, colour, width) {
  g.strokeStyle = colour; g.fillStyle = colour; g.lineWidth = width;
  g.beginPath(); g.moveTo(a, b); g.lineTo(c, d); g.stroke();
  const ang = Math.atan2(d - b, c - a), h = 4 * width + 4;
  g.beginPath(); g.moveTo(c, d);
  g.lineTo(c - h * Math.cos(ang - 0.4), d - h * Math.sin(ang - 0.4));
  g.lineTo(c - h * Math.cos(ang + 0.4), d - h * Math.sin(ang + 0.4)); g.fill();
}
function roleName(r, w) {
  if (r.player_number === 2) return 'controlled';
  if (w && w.striker_known) return w.autonomous_is_striker ? 'striker' : 'supporter';
  return 'autonomous';
}
function penalty(player) {
  const g = state.game;
  if (!g || !g.our_team_found) return 0;
  const p = g.our_team.players[player - 1];
  return p ? p.penalty : 0;
}

// ---------- status, robots, logs ----------
const GAME_STATES = ['INITIAL', 'READY', 'SET', 'PLAYING', 'FINISHED', 'STANDBY'];
const SET_PLAYS = ['', 'goal kick', 'pushing free kick', 'corner kick', 'kick-in', 'penalty kick'];
function mmss(s) { const a = Math.abs(s); return `${s < 0 ? '-' : ''}${Math.floor(a / 60)}:${String(a % 60).padStart(2, '0')}`; }
function renderStatus() {
  const g = state.game;
  if (g) {
    $('game-state').textContent = (GAME_STATES[g.state] || `state ${g.state}`) +
      (g.set_play ? ` (${SET_PLAYS[g.set_play] || g.set_play})` : '') + (g.first_half ? '' : ', 2nd half');
    $('time-left').textContent = mmss(g.secs_remaining);
    $('score').textContent = `us ${g.our_team.score} – ${g.opponent.score} them`;
    $('budget').textContent = g.our_team.message_budget;
  }
  const own = state.local[2];
  if (own) {
    $('whistle').textContent = ['?', 'no', 'HEARD'][own.whistle] || own.whistle;
    if (own.whistle === 2) $('whistle').textContent += ` (${(own.time_since_whistle_ms / 1000).toFixed(1)} s ago)`;
    $('referee').textContent = own.referee_gesture ? `gesture ${own.referee_gesture}` : 'none';
    if (!g) $('budget').textContent = own.message_budget;
  }
  const l = $('link');
  const bad = Object.values(state.links).filter((e) => e.change === 'RobotNotResponding');
  const robots = (state.world && state.world.robots) || [];
  const silent = robots.filter((r) => r.age_s > 1.0).map((r) => r.player_number);
  const down = [...new Set([...bad.map((e) => e.player_number), ...silent])];
  if (down.length) { l.textContent = `robot ${down.join(', ')} not responding`; l.className = 'bad'; }
  else if (robots.length || Object.keys(state.links).length) { l.textContent = 'OK'; l.className = 'good'; }
}
function renderRobots() {
  const tb = $('robots').tBodies[0];
  tb.textContent = '';
  const w = state.world;
  if (!w) return;
  for (const r of w.robots) {
    const tr = tb.insertRow();
    tr.dataset.player = r.player_number;
    tr.dataset.x = r.pose.x_mm; tr.dataset.y = r.pose.y_mm;
    const flags = [r.fallen ? 'fallen' : '', penalty(r.player_number) ? 'penalised' : '', r.age_s > 1 ? 'silent' : ''].filter(Boolean).join(', ') || 'ok';
    for (const v of [r.player_number, roleName(r, w), Math.round(r.pose.x_mm), Math.round(r.pose.y_mm),
      Math.round(r.pose.theta_rad * 180 / Math.PI), flags]) tr.insertCell().textContent = v;
  }
  renderStatus();
}
function addLog(id, text, cls) {
  const ol = $(id);
  const li = document.createElement('li');
  li.textContent = `${new Date().toLocaleTimeString()}  ${text}`;
  if (cls) li.className = cls;
  ol.prepend(li);
  while (ol.children.length > 30) ol.lastChild.remove();
}
function renderHistory(entries) {
  const ol = $('history');
  ol.textContent = '';
  for (const e of entries.slice().reverse()) {
    const li = document.createElement('li');
    li.dataset.status = e.status;
    li.dataset.seq = e.seq;
    const t = new Date(e.at_ms).toLocaleTimeString();
    li.innerHTML = `<span class="t"></span> <span class="label"></span> <span class="badge ${e.status}">${e.status}</span> <span class="reason"></span>`;
    li.querySelector('.t').textContent = t;
    li.querySelector('.label').textContent = e.label;
    li.querySelector('.reason').textContent = e.reason;
    ol.appendChild(li);
  }
}
function renderExec(d) {
  const text = `${d.machine}: ${d.active.join(', ')} (after ${d.event}, step ${d.step})`;
  if (d.machine === 'coach') $('exec-coach').textContent = d.active.join(', ');
  else $('exec-state').textContent = text;
}
function renderBall() {
  const b = state.ball;
  if (!b) return;
  let t = `${b.state}`;
  if (b.found) {
    t += `, window ${b.window.width}x${b.window.height} at (${b.window.x}, ${b.window.y}) px, confidence ${b.confidence.toFixed(2)}`;
    if (b.has_centre_m) t += `, centre (${b.centre_m.map((v) => v.toFixed(2)).join(', ')}) m (camera)`;
    if (b.has_centre_world) t += `, world (${b.centre_world_m.map((v) => v.toFixed(2)).join(', ')}) m`;
  } else t += ', not found';
  $('ball-info').textContent = t;
  drawOverlay();
}
function showCamera(blob) {
  const url = URL.createObjectURL(blob);
  const img = $('camera');
  const meta = state.rgbdNext;
  img.onload = () => {
    if (state.cameraUrl) URL.revokeObjectURL(state.cameraUrl);
    state.cameraUrl = url;
    state.rgbd = meta;
    drawOverlay();
  };
  img.src = url;
  $('camera-none').hidden = true;
}
function drawOverlay() {
  const img = $('camera'), cv = $('camera-overlay');
  cv.width = img.clientWidth; cv.height = img.clientHeight;
  const g = cv.getContext('2d');
  g.clearRect(0, 0, cv.width, cv.height);
  const r = state.rgbd;
  // The track of this very image when the server had it, else the latest.
  const b = (r && r.track) || state.ball;
  if (!b || !b.found || !r || !r.width) return;
  const sx = cv.width / r.width, sy = cv.height / r.height;
  g.strokeStyle = '#00e676'; g.lineWidth = 2;
  g.strokeRect(b.window.x * sx, b.window.y * sy, b.window.width * sx, b.window.height * sy);
  g.fillStyle = '#00e676';
  g.beginPath(); g.arc(b.centre_px[0] * sx, b.centre_px[1] * sy, 3, 0, 2 * Math.PI); g.fill();
}

// ---------- the coach machine (coach_status) ----------
// Ages arrive as of the Executive's publication; between updates they keep counting here, and
// when updates stop for longer than staleAfterMs the block is greyed out and says since when.
function renderCoach() {
  const c = state.coach, box = $('coach-status');
  if (!c) return;
  const sinceMs = Math.max(0, Date.now() - state.clockOffsetMs - c.received_ms);
  const stale = sinceMs > state.staleAfterMs;
  box.classList.toggle('stale', stale);
  box.dataset.stale = String(stale);
  box.dataset.seq = c.seq;
  $('cs-fresh').textContent = stale
    ? `no coach/status for ${(sinceMs / 1000).toFixed(0)} s: last known values (is the Executive running?)`
    : `live (update ${c.seq})`;
  const set = (id, text, cls) => { const e = $(id); e.textContent = text; e.className = cls || ''; };
  set('cs-state', c.state + (c.game ? ` · game ${c.game}` : ' · no game state yet'), c.state.endsWith('playing') ? 'good' : 'wait');
  set('cs-link', c.link_up ? 'up' : 'LOST: robot not responding', c.link_up ? 'good' : 'bad');
  const robot = [c.fallen ? 'fallen' : '', c.penalised ? 'penalised' : ''].filter(Boolean).join(', ');
  set('cs-robot', robot || 'up', robot ? 'bad' : 'good');
  set('cs-pending', c.pending ? `${c.pending.label} (${c.pending.source}): waits, ${c.pending.why}` : 'none', c.pending ? 'wait' : '');
  set('cs-last', c.last ? `${c.last.label}, ${c.last.done ? 'done' : 'in progress'}` : 'none yet', c.last && c.last.done ? 'good' : '');
  set('cs-answer', c.last_answer ? `“${c.last_answer}”` : '–');
  const age = (s) => (s === null || s === undefined ? null : s + sinceMs / 1000);
  const ago = (a) => (a === null ? 'never' : `${a.toFixed(1)} s ago`);
  const ball = age(c.ball_last_seen_s), obst = age(c.obstacle_last_seen_s);
  box.dataset.ballAge = ball === null ? '' : ball.toFixed(2);
  set('cs-ball', ago(ball), ball === null || ball > 5 ? 'bad' : 'good');
  set('cs-obst', `${ago(obst)} (${c.obstacles_tracked} tracked)`);
}
setInterval(renderCoach, 250);

let noticeTimer = null;
function notice(text, ok) {
  const n = $('notice');
  n.textContent = text;
  n.className = ok ? 'ok' : 'error';
  clearTimeout(noticeTimer);
  noticeTimer = setTimeout(() => { n.textContent = ''; n.className = ''; }, ok ? 3000 : 8000);
}

setView(state.view);
connect();
