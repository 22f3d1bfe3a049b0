// The vademecum web viewer: lists the caller's sessions (Sessions.ListSessions) and watches one
// (Viewing.Watch) over gRPC-web, on the same contracts as every other client
// (proto/vademecum/v1). No library: the few messages it reads are decoded from the protobuf
// wire format here, and the surface is drawn with a 2D canvas (painter's algorithm).
//
// Frames: only the latest frame received is drawn, at the display's pace; a frame that arrives
// while an older one waits replaces it (skipped, never queued). The frame handling draws every
// part of OrganDisplacement it knows — the displaced surface coloured by |u|, the walls of a
// cut, the damage of a tearing session — and ignores the rest.
'use strict';

const $ = (id) => document.getElementById(id);
const state = {
  token: localStorage.getItem('vademecum-token') || '',
  watching: null, // { id, abort }
  geometry: null, // [{ organ, ref: Float32Array, tri: Uint32Array, n }]
  latest: null, // the newest frame not drawn yet
  shown: null, // the frame drawn last
  paused: false,
  frames: 0, // frames received (not heartbeats)
  messages: 0,
  arrivals: [], // local times of recent frames (rate)
  bestOffset: Infinity, // min over frames of (local time − session time), for latency
  latency: 0,
  force: [], // [local time s, |F| N]
  umaxScale: 1e-3,
  toolRadius: {}, // session id → its first tool's radius (m), for drawing it
  toolRadii: {}, // session id → { tool name → radius (m) }, for sessions that move named tools
  yaw: 0.6,
  pitch: 0.5,
};

// ---- protobuf wire format -------------------------------------------------------------

/** The fields of a message: field number → array of values (numbers, {f64}, {f32}, bytes). */
function fields(bytes) {
  const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const out = new Map();
  let p = 0;
  const varint = () => {
    let x = 0;
    let s = 1;
    for (;;) {
      const c = bytes[p++];
      x += (c & 0x7f) * s;
      if (c < 0x80) return x;
      s *= 128;
    }
  };
  while (p < bytes.length) {
    const key = varint();
    const f = Math.floor(key / 8);
    const w = key & 7;
    let v;
    if (w === 0) v = varint();
    else if (w === 1) { v = { f64: dv.getFloat64(p, true) }; p += 8; }
    else if (w === 2) { const n = varint(); v = bytes.subarray(p, p + n); p += n; }
    else if (w === 5) { v = { f32: dv.getFloat32(p, true) }; p += 4; }
    else throw new Error('unsupported wire type ' + w);
    if (!out.has(f)) out.set(f, []);
    out.get(f).push(v);
  }
  return out;
}
const one = (m, f) => (m && m.get(f) ? m.get(f)[0] : undefined);
const str = (m, f) => { const v = one(m, f); return v ? new TextDecoder().decode(v) : ''; };
const uint = (m, f) => one(m, f) || 0;
const dbl = (m, f) => { const v = one(m, f); return v ? v.f64 : 0; };
const flag = (m, f) => uint(m, f) !== 0;
const sub = (m, f) => { const v = one(m, f); return v ? fields(v) : null; };
const subs = (m, f) => (m && m.get(f) ? m.get(f).map(fields) : []);
const vec3 = (m) => (m ? [dbl(m, 1), dbl(m, 2), dbl(m, 3)] : [0, 0, 0]);
const f32s = (b) => (b ? new Float32Array(b.slice().buffer) : new Float32Array(0));
const u32s = (b) => (b ? new Uint32Array(b.slice().buffer) : new Uint32Array(0));

/** Encodes `[field, kind, value]` triples (kind: 'string' | 'double' | 'uint'). */
function encode(parts) {
  const out = [];
  const varint = (x) => { while (x >= 128) { out.push((x % 128) | 128); x = Math.floor(x / 128); } out.push(x); };
  for (const [f, kind, v] of parts) {
    if (kind === 'string') {
      const b = new TextEncoder().encode(v);
      varint(f * 8 + 2); varint(b.length); out.push(...b);
    } else if (kind === 'double') {
      varint(f * 8 + 1);
      const b = new Uint8Array(8); new DataView(b.buffer).setFloat64(0, v, true); out.push(...b);
    } else {
      varint(f * 8); varint(v);
    }
  }
  return new Uint8Array(out);
}

// ---- gRPC-web -------------------------------------------------------------------------

class GrpcError extends Error {
  constructor(code, message) { super(message || 'gRPC status ' + code); this.code = code; }
}

/** Calls `method` ("Service/Method" of vademecum.v1) with `body`; `onMessage` gets every
 *  response message (a server stream gives many). Resolves when the call ends with OK. */
async function call(method, body, onMessage, signal) {
  const framed = new Uint8Array(5 + body.length);
  new DataView(framed.buffer).setUint32(1, body.length);
  framed.set(body, 5);
  const headers = { 'content-type': 'application/grpc-web+proto', 'x-grpc-web': '1' };
  if (state.token) headers.authorization = 'Bearer ' + state.token;
  const res = await fetch('vademecum.v1.' + method, { method: 'POST', headers, body: framed, signal });
  const status = res.headers.get('grpc-status');
  if (status && status !== '0') throw new GrpcError(+status, decodeURIComponent(res.headers.get('grpc-message') || ''));
  if (!res.ok) throw new GrpcError(2, 'HTTP ' + res.status);
  const reader = res.body.getReader();
  let buf = new Uint8Array(0);
  for (;;) {
    const { done, value } = await reader.read();
    if (done) return;
    const joined = new Uint8Array(buf.length + value.length);
    joined.set(buf); joined.set(value, buf.length);
    buf = joined;
    while (buf.length >= 5) {
      const n = new DataView(buf.buffer, buf.byteOffset).getUint32(1);
      if (buf.length < 5 + n) break;
      const kind = buf[0];
      const payload = buf.slice(5, 5 + n);
      buf = buf.slice(5 + n);
      if (kind & 0x80) {
        const text = new TextDecoder().decode(payload);
        const code = /grpc-status:\s*(\d+)/i.exec(text);
        if (code && code[1] !== '0') {
          const msg = /grpc-message:\s*([^\r\n]*)/i.exec(text);
          throw new GrpcError(+code[1], decodeURIComponent(msg ? msg[1] : ''));
        }
        return;
      }
      onMessage(payload);
    }
  }
}

// ---- sessions --------------------------------------------------------------------------

function showError(e) {
  $('error').textContent = e ? String(e.message || e) : '';
}

async function listSessions() {
  let list = null;
  try {
    await call('Sessions/ListSessions', new Uint8Array(0), (m) => { list = fields(m); });
  } catch (e) {
    if (e.code === 16) { $('login').classList.add('shown'); showError('a token is needed'); return; }
    showError(e);
    return;
  }
  $('login').classList.remove('shown');
  showError(null);
  const ul = $('sessions');
  ul.textContent = '';
  for (const s of subs(list, 1)) {
    const id = str(s, 1);
    const tools = subs(s, 9);
    if (tools[0]) state.toolRadius[id] = dbl(tools[0], 3);
    state.toolRadii[id] = Object.fromEntries(tools.map((t) => [str(t, 1), dbl(t, 3)]));
    const li = document.createElement('li');
    li.dataset.id = id;
    const label = str(s, 3);
    li.innerHTML = '<div class="id"></div><div class="scene"></div>';
    li.querySelector('.id').textContent = label ? `${label} (${id})` : id;
    li.querySelector('.scene').textContent = `${str(s, 2)}: ${(s.get(4) || []).map((b) => new TextDecoder().decode(b)).join(', ')}`;
    li.onclick = () => watch(id);
    if (state.watching && state.watching.id === id) li.classList.add('active');
    ul.appendChild(li);
  }
  if (!ul.children.length) ul.innerHTML = '<li class="scene">no session yet</li>';
  const wanted = new URLSearchParams(location.search).get('session');
  if (wanted && !state.watching) watch(wanted);
}

function watch(id) {
  if (state.watching) state.watching.abort.abort();
  const abort = new AbortController();
  state.watching = { id, abort };
  Object.assign(state, { geometry: null, latest: null, shown: null, frames: 0, messages: 0, arrivals: [], bestOffset: Infinity, force: [] });
  for (const li of $('sessions').children) li.classList.toggle('active', li.dataset.id === id);
  $('status').textContent = 'watching ' + id;
  const req = encode([[1, 'string', id], [2, 'double', 30]]);
  call('Viewing/Watch', req, onFrame, abort.signal)
    .then(() => { $('status').textContent = 'the session closed'; })
    .catch((e) => { if (e.name !== 'AbortError') showError(e); });
}

// ---- frames ----------------------------------------------------------------------------

function onFrame(bytes) {
  const m = fields(bytes);
  state.messages += 1;
  const geometry = sub(m, 4);
  if (geometry) {
    state.geometry = subs(geometry, 1).map((s) => ({
      organ: str(s, 1), ref: f32s(one(s, 2)), tri: u32s(one(s, 3)), n: uint(s, 4),
    }));
    fitCamera();
    return;
  }
  const now = performance.now() / 1000;
  const time = dbl(m, 3);
  const force = vec3(sub(m, 6));
  const magnitude = Math.hypot(...force);
  state.force.push([now, magnitude]);
  while (state.force.length && state.force[0][0] < now - 10) state.force.shift();
  if (flag(m, 16)) return; // a heartbeat: nothing new to draw
  state.frames += 1;
  state.arrivals.push(now);
  while (state.arrivals.length && state.arrivals[0] < now - 1) state.arrivals.shift();
  const offset = now - time;
  state.bestOffset = Math.min(state.bestOffset, offset);
  state.latency = offset - state.bestOffset;
  const contact = sub(m, 19);
  const tool = sub(m, 20);
  // the newest frame replaces one not drawn yet: late frames are skipped, never queued
  state.latest = {
    time, force, magnitude,
    organs: subs(m, 5).map((o) => ({
      u: f32s(one(o, 1)),
      cut: sub(o, 2),
      damage: sub(o, 3),
    })),
    contact: contact ? { organ: uint(contact, 1), at: vec3(sub(contact, 4)) } : null,
    tool: tool ? vec3(tool) : null,
    // every tool of a session that moves named tools (two hands), each with its own force
    tools: subs(m, 21).map((t) => {
      const c = sub(t, 4);
      const f = vec3(sub(t, 3));
      return {
        name: str(t, 1),
        tool: sub(t, 2) ? vec3(sub(t, 2)) : null,
        force: f,
        magnitude: Math.hypot(...f),
        contact: c ? { organ: uint(c, 1), at: vec3(sub(c, 4)) } : null,
      };
    }),
  };
}

// ---- drawing ---------------------------------------------------------------------------

const camera = { centre: [0, 0, 0], radius: 0.1 };

function fitCamera() {
  let lo = [Infinity, Infinity, Infinity];
  let hi = [-Infinity, -Infinity, -Infinity];
  for (const g of state.geometry) {
    for (let i = 0; i < g.ref.length; i += 3) {
      for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], g.ref[i + k]); hi[k] = Math.max(hi[k], g.ref[i + k]); }
    }
  }
  camera.centre = [0, 1, 2].map((k) => (lo[k] + hi[k]) / 2);
  camera.radius = Math.max(1e-6, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
}

/** View transform: orbit about the centre by yaw (about z) and pitch. */
function viewer() {
  const [cy, sy, cp, sp] = [Math.cos(state.yaw), Math.sin(state.yaw), Math.cos(state.pitch), Math.sin(state.pitch)];
  const [cx, cyy, cz] = camera.centre;
  return (x, y, z) => {
    const dx = x - cx, dy = y - cyy, dz = z - cz;
    const rx = cy * dx - sy * dy;
    const ry = sy * dx + cy * dy;
    // screen x = rx, screen up = z tilted by the pitch, depth = ry tilted
    return [rx, cp * dz - sp * ry, sp * dz + cp * ry];
  };
}

/** A colour for t in [0, 1]: dark blue → teal → yellow (perceptually ordered), blended
 *  towards damage red by `hurt` in [0, 1], darkened by `shade`. */
function colour(t, shade, hurt = 0) {
  t = Math.max(0, Math.min(1, t));
  const stops = [[0.18, 0.2, 0.45], [0.1, 0.55, 0.55], [0.45, 0.78, 0.35], [0.98, 0.85, 0.2]];
  const x = t * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(x));
  const f = x - i;
  const red = [0.85, 0.1, 0.1];
  const c = stops[i].map((a, k) => a + (stops[i + 1][k] - a) * f).map((v, k) => v + (red[k] - v) * hurt);
  return `rgb(${c.map((v) => Math.round(255 * v * shade)).join(',')})`;
}

function draw() {
  requestAnimationFrame(draw);
  const canvas = $('canvas');
  const dpr = window.devicePixelRatio || 1;
  const w = canvas.clientWidth * dpr, h = canvas.clientHeight * dpr;
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  updateReadouts();
  drawPlot();
  if (!state.geometry || state.paused) return;
  const frame = state.latest || state.shown;
  if (state.latest) { state.shown = state.latest; state.latest = null; }
  const ctx = canvas.getContext('2d');
  ctx.fillStyle = '#12161c';
  ctx.fillRect(0, 0, w, h);
  const view = viewer();
  const scale = 0.45 * Math.min(w, h) / camera.radius;
  const project = (v) => [w / 2 + scale * v[0], h / 2 - scale * v[1]];
  const tris = [];
  let umax = 0;
  let damageMax = null; // [largest damage, torn threshold] of a tearing organ
  state.geometry.forEach((g, o) => {
    const u = frame && frame.organs[o] ? frame.organs[o].u : null;
    // a tearing organ's damage per surface triangle: blended in red, hidden once torn
    const damage = frame && frame.organs[o] ? frame.organs[o].damage : null;
    const dmg = damage ? f32s(one(damage, 2)) : null;
    const torn = damage && one(damage, 3) ? one(damage, 3).f32 : 1;
    if (dmg && dmg.length) damageMax = [Math.max(...dmg), torn];
    const pos = new Float32Array(g.ref.length);
    const mag = new Float32Array(g.n);
    for (let i = 0; i < g.n; i++) {
      const d = u && u.length === 3 * g.n ? [u[3 * i], u[3 * i + 1], u[3 * i + 2]] : [0, 0, 0];
      pos[3 * i] = g.ref[3 * i] + d[0]; pos[3 * i + 1] = g.ref[3 * i + 1] + d[1]; pos[3 * i + 2] = g.ref[3 * i + 2] + d[2];
      mag[i] = Math.hypot(d[0], d[1], d[2]);
      umax = Math.max(umax, mag[i]);
    }
    const v = [];
    for (let i = 0; i < g.n; i++) v.push(view(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]));
    for (let t = 0; t < g.tri.length; t += 3) {
      const [a, b, c] = [g.tri[t], g.tri[t + 1], g.tri[t + 2]];
      const d = dmg && dmg.length === g.tri.length / 3 ? dmg[t / 3] : 0;
      if (d >= torn) continue;
      tris.push({ v: [v[a], v[b], v[c]], m: (mag[a] + mag[b] + mag[c]) / 3, hurt: Math.min(1, d / torn) });
    }
    const cut = frame && frame.organs[o] ? frame.organs[o].cut : null;
    if (cut) {
      const cp = f32s(one(cut, 3)), cd = f32s(one(cut, 6)), ct = u32s(one(cut, 4));
      const cv = [];
      for (let i = 0; i + 2 < cp.length; i += 3) {
        const dd = cd.length === cp.length ? [cd[i], cd[i + 1], cd[i + 2]] : [0, 0, 0];
        cv.push(view(cp[i] + dd[0], cp[i + 1] + dd[1], cp[i + 2] + dd[2]));
      }
      for (let t = 0; t + 2 < ct.length; t += 3) tris.push({ v: [cv[ct[t]], cv[ct[t + 1]], cv[ct[t + 2]]], wall: true });
    }
  });
  state.umaxShown = umax;
  state.damageShown = damageMax;
  state.umaxScale = Math.max(umax, 0.97 * state.umaxScale, 1e-4);
  tris.sort((p, q) => (p.v[0][2] + p.v[1][2] + p.v[2][2]) - (q.v[0][2] + q.v[1][2] + q.v[2][2]));
  for (const t of tris) {
    const [a, b, c] = t.v;
    if (!a || !b || !c) continue;
    const e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    const e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    const n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    const len = Math.hypot(...n) || 1;
    const shade = 0.35 + 0.65 * Math.abs(n[2] / len);
    const [pa, pb, pc] = [project(a), project(b), project(c)];
    ctx.beginPath(); ctx.moveTo(...pa); ctx.lineTo(...pb); ctx.lineTo(...pc); ctx.closePath();
    ctx.fillStyle = t.wall ? `rgb(${Math.round(200 * shade)},40,40)` : colour(t.m / state.umaxScale, shade, t.hurt);
    ctx.fill();
  }
  const id = state.watching ? state.watching.id : null;
  if (frame && frame.tools && frame.tools.length) {
    for (const t of frame.tools) {
      if (t.tool || t.contact) drawTool(ctx, view, project, scale, t, ((state.toolRadii[id] || {})[t.name]) || 0, t.name);
    }
  } else if (frame && (frame.tool || frame.contact)) {
    drawTool(ctx, view, project, scale, frame, state.toolRadius[id] || 0, null);
  }
  drawScaleBar(ctx, w, h, dpr);
}

/** A tool where it is (a probe's tip drawn at its `radius`; where it touches when the frame
 *  does not say), and the force on it from there (the tissue's reaction: what the haptic
 *  device renders; a tenth of the organ's size per newton), with its `name` beside it when
 *  the session moves several. */
function drawTool(ctx, view, project, scale, frame, radius, name) {
  const at = frame.tool || frame.contact.at;
  const p = project(view(...at));
  const arrow = camera.radius * 0.2;
  const tip = project(view(at[0] + frame.force[0] * arrow, at[1] + frame.force[1] * arrow, at[2] + frame.force[2] * arrow));
  ctx.strokeStyle = '#f4f4f4'; ctx.fillStyle = '#f4f4f4'; ctx.lineWidth = 3;
  ctx.beginPath(); ctx.arc(p[0], p[1], Math.max(4, radius * scale), 0, 2 * Math.PI); ctx.stroke();
  if (frame.magnitude > 0) {
    ctx.beginPath(); ctx.moveTo(...p); ctx.lineTo(...tip); ctx.stroke();
    ctx.beginPath(); ctx.arc(tip[0], tip[1], 4, 0, 2 * Math.PI); ctx.fill();
  }
  if (name) {
    ctx.font = `${13 * (window.devicePixelRatio || 1)}px system-ui`;
    ctx.textAlign = 'left';
    ctx.fillText(`${name} ${frame.magnitude.toFixed(2)} N`, p[0] + Math.max(6, radius * scale) + 4, p[1] - 4);
  }
}

function drawScaleBar(ctx, w, h, dpr) {
  const [x, y, bw, bh] = [w - 40 * dpr, 40 * dpr, 14 * dpr, h * 0.4];
  for (let i = 0; i < bh; i += 2) { ctx.fillStyle = colour(1 - i / bh, 1); ctx.fillRect(x, y + i, bw, 2); }
  ctx.fillStyle = '#dfe6ee';
  ctx.font = `${12 * dpr}px system-ui`;
  ctx.textAlign = 'right';
  ctx.fillText(`${(1e3 * state.umaxScale).toFixed(2)} mm`, x - 4, y + 10 * dpr);
  ctx.fillText('0 mm', x - 4, y + bh);
  ctx.fillText('|u|', x + bw, y - 8 * dpr);
}

function drawPlot() {
  const c = $('plot');
  const dpr = window.devicePixelRatio || 1;
  const w = c.clientWidth * dpr, h = c.clientHeight * dpr;
  if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
  const ctx = c.getContext('2d');
  ctx.fillStyle = '#1b222b'; ctx.fillRect(0, 0, w, h);
  const now = performance.now() / 1000;
  const top = Math.max(0.5, ...state.force.map((f) => f[1])) * 1.1;
  ctx.strokeStyle = '#e0a040'; ctx.lineWidth = 2 * dpr; ctx.beginPath();
  state.force.forEach(([t, f], i) => {
    const px = w * (1 - (now - t) / 10), py = h - 6 * dpr - (h - 20 * dpr) * f / top;
    if (i) ctx.lineTo(px, py); else ctx.moveTo(px, py);
  });
  ctx.stroke();
  ctx.fillStyle = '#8b98a8'; ctx.font = `${12 * dpr}px system-ui`;
  ctx.fillText(`|F| over the last 10 s (top ${top.toFixed(2)} N)`, 8 * dpr, 16 * dpr);
}

function updateReadouts() {
  $('frames').textContent = String(state.frames);
  $('fps').textContent = state.arrivals.length ? `${state.arrivals.length} Hz` : '–';
  $('latency').textContent = isFinite(state.bestOffset) ? `+${(1e3 * state.latency).toFixed(0)} ms over the best` : '–';
  const f = state.shown || state.latest;
  if (f) {
    $('time').textContent = `${f.time.toFixed(2)} s`;
    $('force').textContent = `${f.magnitude.toFixed(3)} N`;
    // two hands: every tool's force by name
    $('tools').textContent = f.tools && f.tools.length
      ? f.tools.map((t) => `${t.name} ${t.magnitude.toFixed(3)} N`).join(' · ') : '–';
    $('umax').textContent = `${(1e3 * (state.umaxShown || 0)).toFixed(3)} mm`;
    $('damage').textContent = state.damageShown
      ? `${state.damageShown[0].toFixed(2)} (torn at ${state.damageShown[1].toFixed(2)}; red)` : '–';
  }
}

// ---- controls --------------------------------------------------------------------------

let drag = null;
$('canvas').addEventListener('pointerdown', (e) => { drag = [e.clientX, e.clientY]; });
window.addEventListener('pointerup', () => { drag = null; });
window.addEventListener('pointermove', (e) => {
  if (!drag) return;
  state.yaw += (e.clientX - drag[0]) * 0.01;
  state.pitch = Math.max(-1.5, Math.min(1.5, state.pitch + (e.clientY - drag[1]) * 0.01));
  drag = [e.clientX, e.clientY];
});
$('pause').onclick = () => { state.paused = !state.paused; $('pause').textContent = state.paused ? 'Resume' : 'Pause'; };
$('refresh').onclick = listSessions;
$('token-ok').onclick = () => {
  state.token = $('token').value.trim();
  localStorage.setItem('vademecum-token', state.token);
  listSessions();
};

listSessions();
setInterval(listSessions, 5000);
requestAnimationFrame(draw);
