// The bistable dashboard: plain JavaScript and canvas, no library. It polls the JSON API of
// server/dashboard.cc (docs/dashboard.md) and never sees a token: one typed into the form is sent once
// in an Authorization header to /api/session, which keeps it in an HttpOnly cookie.
'use strict';

const $ = (id) => document.getElementById(id);
const state = { sweep: null, info: null, map: null, mask: null, fixed: {}, timer: 0, lastWorkers: {}, lastPoll: 0 };

// ---- colours: the CLI figures' palettes, for the page and the tests (stops, linear between) ----
const STOPS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];  // viridis
// Metrics whose sign is their meaning (the map says "diverging": frf_db, lle): blue below 0, white at 0, red
// above, on a range symmetric about 0.
const DIVERGING = [[33, 102, 172], [255, 255, 255], [178, 24, 43]];
const CATEGORY = [[27, 158, 119], [217, 95, 2], [117, 112, 179], [231, 41, 138], [102, 166, 30], [230, 171, 2], [166, 118, 29], [102, 102, 102]];
const MISSING = [225, 225, 225];

function colorOf(v, map) {
  if (v === null || v === undefined) return MISSING;
  if (map.categories.length) {
    const k = map.categories.findIndex((c) => c[0] === v);
    return k < 0 ? MISSING : categoryColour(map.categories[k], k);
  }
  const [lo, hi] = colourRange(map), stops = map.diverging ? DIVERGING : STOPS;
  let t = hi > lo ? (v - lo) / (hi - lo) : 0.5;
  t = Math.min(1, Math.max(0, t)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(t)), f = t - i;
  return stops[i].map((a, c) => Math.round(a + f * (stops[i + 1][c] - a)));
}

// A category's colour: the server's (the CLI figures' for named codes, e.g. motion), else by position.
function categoryColour(cat, k) {
  const hex = cat[2];
  if (typeof hex === 'string' && /^#[0-9a-f]{6}$/i.test(hex)) return [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16));
  return CATEGORY[k % CATEGORY.length];
}

// The values the colour scale spans: the map's range, or for a diverging metric ±the larger magnitude.
function colourRange(map) {
  if (!map.diverging) return [map.min, map.max];
  const m = Math.max(Math.abs(map.min), Math.abs(map.max), 1e-12);
  return [-m, m];
}

// ---- the API ----
async function api(path, params) {
  const q = params ? '?' + new URLSearchParams(params).toString() : '';
  const r = await fetch('/api/' + path + q, { credentials: 'same-origin' });
  const text = await r.text();
  let body;
  try { body = JSON.parse(text); } catch (e) { body = { error: text.trim() || 'bad answer' }; }  // a 503 "busy" is text
  if (r.status === 401) { showLogin(); throw new Error('sign in'); }
  // A cell over the dashboard's bound (422) comes with the `bistable point` command that computes it.
  if (!r.ok) throw new Error((body.error || r.statusText) + (body.command ? ': ' + body.command : ''));
  return body;
}

function showLogin() { $('login').hidden = false; }

async function signIn(ev) {
  ev.preventDefault();
  const token = $('token').value.trim();
  $('token').value = '';  // the page keeps no token
  const r = await fetch('/api/session', { headers: { Authorization: 'Bearer ' + token }, credentials: 'same-origin' });
  if (!r.ok) { $('login-error').textContent = 'refused (' + r.status + ')'; return; }
  $('login').hidden = true;
  $('login-error').textContent = '';
  start();
}

// ---- small DOM helpers ----
function el(tag, text, cls) {
  const e = document.createElement(tag);
  if (text !== undefined) e.textContent = text;
  if (cls) e.className = cls;
  return e;
}
function row(cells) {
  const tr = el('tr');
  for (const c of cells) { const td = el('td'); if (c instanceof Node) td.appendChild(c); else td.textContent = c; tr.appendChild(td); }
  return tr;
}
function fmt(v, digits = 4) {
  if (v === null || v === undefined) return '–';
  if (typeof v !== 'number') return String(v);
  return Number.isInteger(v) ? String(v) : v.toPrecision(digits);
}
function duration(s) {
  if (s === null || s === undefined) return '–';
  s = Math.round(s);
  return s >= 3600 ? Math.floor(s / 3600) + ' h ' + Math.floor((s % 3600) / 60) + ' min' : s >= 60 ? Math.floor(s / 60) + ' min ' + (s % 60) + ' s' : s + ' s';
}

// ---- sweeps and workers, polled every second ----
async function pollSweeps() {
  const d = await api('sweeps');
  const now = performance.now() / 1000, dt = state.lastPoll ? now - state.lastPoll : 0;
  state.lastPoll = now;
  const tb = $('sweeps').tBodies[0];
  tb.replaceChildren();
  for (const s of d.sweeps.slice().reverse()) {
    const bar = el('span', undefined, 'bar'), fill = el('span');
    fill.style.width = (s.items_total ? (100 * s.items_done) / s.items_total : 0).toFixed(1) + '%';
    bar.appendChild(fill);
    const tr = row([s.id, s.name, s.model, s.state, bar, s.items_done + ' / ' + s.items_total, fmt(s.items_per_second, 3),
      duration(s.eta_seconds), s.owner, s.workers]);
    tr.dataset.id = s.id;
    if (state.sweep === s.id) tr.className = 'sel';
    tr.onclick = () => openSweep(s.id);
    tb.appendChild(tr);
    if (state.sweep === s.id && state.info && state.info.status.state !== s.state) openSweep(s.id);
    if (state.sweep === s.id) state.info.status = s;
  }
  const wb = $('workers').tBodies[0];
  wb.replaceChildren();
  const seen = {};
  for (const w of d.workers) {
    const before = state.lastWorkers[w.name];
    const rate = before !== undefined && dt > 0 ? (w.items_done - before) / dt : null;
    seen[w.name] = w.items_done;
    wb.appendChild(row([w.name, w.leases, w.items_done, fmt(rate, 3), w.last_seen || '–']));
  }
  state.lastWorkers = seen;
}

// ---- one sweep: spec, axes, map ----
async function openSweep(id) {
  if (state.sweep !== id) { $('cell-view').hidden = true; state.cell = null; }
  state.sweep = id;
  state.mask = null;
  $('query-result').textContent = '';
  const info = await api('sweep', { id });
  state.info = info;
  $('sweep-view').hidden = false;
  $('sweep-title').textContent = 'sweep ' + info.status.id + (info.status.name ? ' — ' + info.status.name : '') + ' (' + info.status.state + ')';
  $('spec').textContent = info.spec;
  const metric = $('metric');
  const keep = metric.value;
  metric.replaceChildren(...info.metrics.map((m) => { const o = el('option', m.name + (m.unit ? ' [' + m.unit + ']' : '')); o.value = m.name; return o; }));
  const wanted = new URLSearchParams(location.hash.slice(1)).get('metric') || keep;
  if (info.metrics.some((m) => m.name === wanted)) metric.value = wanted;
  const names = info.axes.map((a) => a.name);
  fillAxisSelect($('x-axis'), names, names[names.length - 1]);
  fillAxisSelect($('y-axis'), names, names.length > 1 ? names[0] : '');
  buildFixed();
  await drawMap();
}

function fillAxisSelect(sel, names, def) {
  const keep = sel.value;
  sel.replaceChildren(...names.map((n) => { const o = el('option', n); o.value = n; return o; }));
  if (sel.id === 'y-axis') sel.prepend(Object.assign(el('option', '—'), { value: '' }));
  sel.value = names.includes(keep) ? keep : def;
}

// A select for every dimension that is neither x nor y: the other axes, and the item dimension by the
// name the map files give it (/api/sweep's item_dim: "ic", or "direction" for up/down continuation).
function buildFixed() {
  const box = $('fixed');
  box.replaceChildren();
  const info = state.info, x = $('x-axis').value, y = $('y-axis').value;
  const dims = info.axes.map((a) => ({ name: a.name, labels: a.values.map((v) => fmt(v)) }));
  if (info.item_dim) {
    const n = info.ic_count, labels = info.item_dim === 'direction' ? ['up', 'down'] : [...Array(n).keys()].map(String);
    dims.push({ name: info.item_dim, labels: labels.slice(0, n) });
  }
  for (const d of dims) {
    if (d.name === x || d.name === y) continue;
    const sel = el('select');
    d.labels.forEach((l, i) => { const o = el('option', l); o.value = i; sel.appendChild(o); });
    sel.value = Math.min(state.fixed[d.name] || 0, d.labels.length - 1);
    sel.onchange = () => { state.fixed[d.name] = +sel.value; drawMap(); };
    const lab = el('label', d.name + ' ');
    lab.appendChild(sel);
    box.appendChild(lab);
  }
}

function sliceParams() {
  const p = { id: state.sweep, metric: $('metric').value, x: $('x-axis').value };
  if ($('y-axis').value) p.y = $('y-axis').value;
  const at = [];
  for (const lab of $('fixed').children) at.push(lab.firstChild.textContent.trim() + ':' + lab.lastChild.value);
  if (at.length) p.at = at.join(',');
  return p;
}

// The open sweep and map in the URL's fragment (#sweep=ID&metric=NAME): a view can be bookmarked, shared
// and opened by a script (docs/dashboard.md).
function saveHash() {
  if (!state.sweep) return;
  const h = new URLSearchParams({ sweep: state.sweep });
  if ($('metric').value) h.set('metric', $('metric').value);
  history.replaceState(null, '', '#' + h.toString());
}

async function drawMap() {
  saveHash();
  if (!state.info || !state.info.metrics.length) return;
  try {
    state.map = await api('map', sliceParams());
    const m = state.map, notes = [];
    if (m.note) notes.push(m.note);
    else if (m.partial) notes.push('partial: what is stored so far (grey: not yet)');
    for (const [k, a] of [['x', m.x], ['y', m.y]])  // a slice side over 1024 cells: every stride-th shown
      if (a && a.stride > 1) notes.push('decimated: 1 of every ' + a.stride + ' cells shown along ' + k + ' (' + a.values.length + ' of ' + a.size + ')');
    $('map-state').textContent = notes.join('; ');
  } catch (e) {
    state.map = null;
    $('map-state').textContent = e.message;
  }
  render();
  if (state.map && $('query').value.trim()) runQuery();
}

// ---- the heatmap ----
const M = { left: 80, right: 125, top: 12, bottom: 44 };  // right: the colour bar or legend (chaotic_mixed)

function geometry() {
  const c = $('map'), m = state.map;
  const nx = m.x ? m.x.values.length : 1, ny = m.y ? m.y.values.length : 1;
  const w = c.width - M.left - M.right, h = c.height - M.top - M.bottom;
  return { nx, ny, w, h, cw: w / nx, ch: h / ny };
}

// Canvas position of the centre of cell (ix, iy); iy = 0 is the bottom row.
function cellCenter(ix, iy) {
  const g = geometry();
  return [M.left + (ix + 0.5) * g.cw, M.top + g.h - (iy + 0.5) * g.ch];
}

function render() {
  const c = $('map'), ctx = c.getContext('2d'), m = state.map;
  ctx.clearRect(0, 0, c.width, c.height);
  if (!m) return;
  const g = geometry();
  const img = ctx.createImageData(g.nx, g.ny);
  for (let iy = 0; iy < g.ny; ++iy)
    for (let ix = 0; ix < g.nx; ++ix) {
      const rgb = colorOf(m.values[iy * g.nx + ix], m), o = 4 * ((g.ny - 1 - iy) * g.nx + ix);
      img.data[o] = rgb[0]; img.data[o + 1] = rgb[1]; img.data[o + 2] = rgb[2]; img.data[o + 3] = 255;
    }
  const off = document.createElement('canvas');
  off.width = g.nx; off.height = g.ny;
  off.getContext('2d').putImageData(img, 0, 0);
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(off, M.left, M.top, g.w, g.h);
  if (state.mask) {  // query matches: outlined cells, black with a white core (no map uses that pair:
    // a red outline read as "chaotic" on the motion map and vanished into FRF reds; docs/figures.md)
    const lw = Math.max(1, Math.min(2, g.cw / 4));
    for (const [colour, width] of [['#000000', lw + 1], ['#ffffff', Math.max(0.5, lw - 0.5)]]) {
      ctx.strokeStyle = colour;
      ctx.lineWidth = width;
      for (let iy = 0; iy < g.ny; ++iy)
        for (let ix = 0; ix < g.nx; ++ix)
          if (state.mask[iy * g.nx + ix]) ctx.strokeRect(M.left + ix * g.cw + 0.5, M.top + g.h - (iy + 1) * g.ch + 0.5, g.cw - 1, g.ch - 1);
    }
  }
  ctx.fillStyle = '#222';
  ctx.font = '12px sans-serif';
  // Ticks at round numbers (1, 2 or 5 times a power of ten, about 6 of them), placed between the grid
  // values they fall between (the grid's own values, 0.522 or 1.03, are not tick labels).
  const ticks = (axis, n, horizontal) => {
    const v = axis.values, lo = v[0], hi = v[n - 1];
    if (!(hi > lo)) return;
    const raw = (hi - lo) / 6, p = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 5, 10].map((k) => k * p).find((x) => x >= raw);
    const decimals = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
    for (let t = Math.ceil(lo / step - 1e-9) * step; t <= hi + 1e-9 * step; t += step) {
      let i = 0;
      while (i + 2 < n && v[i + 1] < t) ++i;
      const pos = n > 1 ? i + Math.min(1, Math.max(0, (t - v[i]) / (v[i + 1] - v[i]))) : 0;
      const label = (Math.abs(t) < step * 1e-9 ? 0 : t).toFixed(decimals);
      if (horizontal) ctx.fillText(label, M.left + (pos + 0.5) * g.cw - 10, M.top + g.h + 16);
      else ctx.fillText(label, 22, M.top + g.h - (pos + 0.5) * g.ch + 4);
    }
  };
  if (m.x) { ticks(m.x, g.nx, true); ctx.fillText(m.x.name + ' [' + m.x.unit + ']', M.left + g.w / 2 - 30, c.height - 8); }
  if (m.y) {
    ticks(m.y, g.ny, false);
    ctx.save(); ctx.translate(12, M.top + g.h / 2 + 50); ctx.rotate(-Math.PI / 2); ctx.fillText(m.y.name + ' [' + m.y.unit + ']', 0, 0); ctx.restore();
  }
  // Colour bar, or the categories' legend.
  const bx = c.width - M.right + 16;
  if (m.categories.length) {
    m.categories.forEach((cat, k) => {
      ctx.fillStyle = 'rgb(' + categoryColour(cat, k).join(',') + ')';
      ctx.fillRect(bx, M.top + 18 * k, 14, 14);
      ctx.fillStyle = '#222';
      ctx.fillText(cat[1], bx + 18, M.top + 18 * k + 11);
    });
  } else if (m.min !== null) {
    const [lo, hi] = colourRange(m);
    for (let k = 0; k < g.h; ++k) {
      const v = lo + ((hi - lo) * (g.h - 1 - k)) / Math.max(1, g.h - 1);
      ctx.fillStyle = 'rgb(' + colorOf(v, m).join(',') + ')';
      ctx.fillRect(bx, M.top + k, 14, 1);
    }
    ctx.fillStyle = '#222';
    ctx.fillText(fmt(hi, 3), bx + 18, M.top + 10);
    ctx.fillText(fmt(lo, 3), bx + 18, M.top + g.h);
    ctx.fillText(m.unit, bx, M.top + g.h + 16);
  }
}

// The cell under a mouse event: {ix, iy} or null.
function cellAt(ev) {
  if (!state.map) return null;
  const g = geometry(), r = $('map').getBoundingClientRect();
  const px = ev.clientX - r.left - M.left, py = ev.clientY - r.top - M.top;
  if (px < 0 || py < 0 || px >= g.w || py >= g.h) return null;
  return { ix: Math.floor(px / g.cw), iy: g.ny - 1 - Math.floor(py / g.ch) };
}

// Row-major point index (last axis fastest) and initial condition of a slice cell; a decimated slice
// shows every stride-th cell, so shown cell ix is axis index ix * stride.
function itemOf(cell) {
  const info = state.info, x = $('x-axis').value, y = $('y-axis').value, m = state.map;
  const sx = m && m.x ? m.x.stride : 1, sy = m && m.y ? m.y.stride : 1;
  let point = 0;
  for (const a of info.axes) {
    const i = a.name === x ? cell.ix * sx : a.name === y ? cell.iy * sy : state.fixed[a.name] || 0;
    point = point * a.values.length + i;
  }
  return { point, ic: info.item_dim ? state.fixed[info.item_dim] || 0 : 0 };
}

function hover(ev) {
  const tip = $('tip'), cell = cellAt(ev), m = state.map;
  if (!cell) { tip.hidden = true; return; }
  const g = geometry(), v = m.values[cell.iy * g.nx + cell.ix];
  const cat = m.categories.find((c) => c[0] === v);
  let text = '';
  if (m.x) text += m.x.name + ' = ' + fmt(m.x.values[cell.ix], 6) + '\n';
  if (m.y) text += m.y.name + ' = ' + fmt(m.y.values[cell.iy], 6) + '\n';
  text += m.metric + ' = ' + (cat ? cat[1] : fmt(v, 6)) + (m.unit && !cat ? ' ' + m.unit : '') + '\nclick: compute this cell';
  tip.textContent = text;
  tip.hidden = false;
  tip.style.left = ev.offsetX + 14 + 'px';
  tip.style.top = ev.offsetY + 10 + 'px';
}

// ---- query ----
async function runQuery(ev) {
  if (ev) ev.preventDefault();
  const q = $('query').value.trim();
  if (!q || !state.map) return;
  try {
    const r = await api('query', Object.assign(sliceParams(), { q }));
    state.mask = r.mask;
    $('query-result').textContent = r.count + ' of ' + r.total + ' cells (' + (100 * r.fraction).toFixed(2) + ' %), area fraction ' +
      (100 * r.area_fraction).toFixed(2) + ' %' + (r.partial ? ' (of what is stored so far)' : '');
    $('query-result').className = '';
  } catch (e) {
    state.mask = null;
    $('query-result').textContent = e.message;
    $('query-result').className = 'err';
  }
  render();
}

// ---- a cell, computed on demand ----
async function openCell(ev) {
  const cell = cellAt(ev);
  if (!cell) return;
  if (!state.info.cells) { $('map-state').textContent = state.info.cell_note; return; }
  const item = itemOf(cell);
  $('cell-view').hidden = false;
  $('cell-title').textContent = 'computing point ' + item.point + ' …';
  let d;
  try {
    d = await api('cell', { id: state.sweep, point: item.point, ic: item.ic });
  } catch (e) {
    $('cell-title').textContent = e.message;
    return;
  }
  showCell(d);
}

function showCell(d) {
  state.cell = d;
  const at = Object.entries(d.at).map(([k, v]) => k + ' = ' + fmt(v, 6)).join(', ');
  $('cell-title').textContent = 'cell ' + d.point + (d.ic ? ' (ic ' + d.ic + ')' : '') + ': ' + at;
  $('cell-command').textContent = d.command;
  $('cell-note').textContent = d.command_note;
  $('cell-refine').textContent = d.refine_note || '';
  $('cell-refine').hidden = !d.refine_note;
  const r = d.result, rows = d.series.rows;
  const tb = $('cell-metrics');
  tb.replaceChildren();
  const flat = [];
  for (const [k, v] of Object.entries(r)) {
    if (k === 'settings' || k === 'hd_peaks') continue;
    if (v !== null && typeof v === 'object') for (const [k2, v2] of Object.entries(v)) flat.push([k + '.' + k2, v2]);
    else flat.push([k, v]);
  }
  flat.push(['hd_peaks', r.hd_peaks.map((p) => fmt(p.freq, 4) + '@' + fmt(p.amp, 3)).join(', ') || '–']);
  for (let i = 0; i < flat.length; i += 2) {
    const tr = el('tr');
    for (const [k, v] of flat.slice(i, i + 2)) {
      tr.appendChild(el('th', k));
      const td = el('td', typeof v === 'number' ? String(v) : v === null ? 'null' : String(v));
      td.dataset.metric = k;
      tr.appendChild(td);
    }
    tb.appendChild(tr);
  }
  const col = (j) => rows.map((q) => q[j]);
  plot($('orbit'), [{ xs: col(1), ys: col(2), line: true }], { xlabel: 'y_m', ylabel: "y_m'" });
  plot($('series'), [{ xs: col(0), ys: col(1), line: true }], { xlabel: 'tau', ylabel: 'y_m' });
  if (d.spectrum) {
    const omega = r.settings.omega, xs = d.spectrum.amp.map((_, k) => (k * d.spectrum.d_omega) / omega);
    const ys = d.spectrum.amp.map((a) => Math.log10(Math.max(a, 1e-16)));
    const keep = xs.map((x) => x <= 8);
    plot($('spectrum'), [{ xs: xs.filter((_, k) => keep[k]), ys: ys.filter((_, k) => keep[k]), line: true }],
      { xlabel: 'omega / Omega', ylabel: 'log10 amplitude', marks: r.hd_peaks.map((p) => p.freq / omega) });
  } else {
    plot($('spectrum'), [], { xlabel: 'diverged', ylabel: '' });
  }
  plot($('section'), [{ xs: d.section.map((p) => p[0]), ys: d.section.map((p) => p[1]), line: false }],
    { xlabel: 'y_m', ylabel: "y_m'" });
}

// A small line or scatter plot with axis ranges and ticks at the ends; marks: vertical lines at x.
function plot(canvas, series, opt) {
  const ctx = canvas.getContext('2d'), W = canvas.width, H = canvas.height, L = 52, B = 30, T = 8, R = 10;
  ctx.clearRect(0, 0, W, H);
  const xs = series.flatMap((s) => s.xs).filter(Number.isFinite), ys = series.flatMap((s) => s.ys).filter(Number.isFinite);
  ctx.fillStyle = '#222';
  ctx.font = '11px sans-serif';
  ctx.fillText(opt.xlabel, L + (W - L - R) / 2 - 10, H - 4);
  ctx.save(); ctx.translate(10, T + (H - T - B) / 2 + 20); ctx.rotate(-Math.PI / 2); ctx.fillText(opt.ylabel, 0, 0); ctx.restore();
  if (!xs.length) return;
  let [x0, x1, y0, y1] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
  if (x1 === x0) { x0 -= 1; x1 += 1; }
  if (y1 === y0) { y0 -= 1; y1 += 1; }
  const px = (x) => L + ((x - x0) / (x1 - x0)) * (W - L - R), py = (y) => H - B - ((y - y0) / (y1 - y0)) * (H - T - B);
  ctx.strokeStyle = '#999';
  ctx.strokeRect(L, T, W - L - R, H - T - B);
  ctx.fillText(fmt(x0, 3), L, H - B + 12);
  ctx.fillText(fmt(x1, 3), W - R - 30, H - B + 12);
  ctx.fillText(fmt(y1, 3), 14, T + 10);
  ctx.fillText(fmt(y0, 3), 14, H - B);
  for (const x of opt.marks || []) {
    if (x < x0 || x > x1) continue;
    ctx.strokeStyle = '#e33';
    ctx.beginPath(); ctx.moveTo(px(x), T); ctx.lineTo(px(x), H - B); ctx.stroke();
  }
  for (const s of series) {
    ctx.strokeStyle = ctx.fillStyle = '#2166ac';
    ctx.beginPath();
    for (let i = 0; i < s.xs.length; ++i) {
      if (!Number.isFinite(s.xs[i]) || !Number.isFinite(s.ys[i])) continue;
      if (s.line) { if (i) ctx.lineTo(px(s.xs[i]), py(s.ys[i])); else ctx.moveTo(px(s.xs[i]), py(s.ys[i])); }
      else ctx.fillRect(px(s.xs[i]) - 1, py(s.ys[i]) - 1, 2, 2);
    }
    if (s.line) ctx.stroke();
  }
}

// ---- start ----
async function tick() {
  try {
    await pollSweeps();
    if (state.sweep && state.info && !['done', 'failed', 'cancelled'].includes(state.info.status.state)) await drawMap();
  } catch (e) { /* shown where it happened; try again next second */ }
}

async function start() {
  try {
    const s = await api('session');
    $('who').textContent = s.auth ? 'signed in as ' + s.who + ' (' + s.role + ')' : 'open (loopback, no tokens)';
  } catch (e) { return; }
  await tick();
  const wanted = new URLSearchParams(location.hash.slice(1)).get('sweep');
  if (wanted && state.sweep !== wanted) await openSweep(wanted).catch(() => {});
  clearInterval(state.timer);
  state.timer = setInterval(tick, 1000);
}

document.addEventListener('DOMContentLoaded', () => {
  $('login').onsubmit = signIn;
  $('metric').onchange = () => { state.mask = null; drawMap(); };
  $('x-axis').onchange = $('y-axis').onchange = () => { buildFixed(); state.mask = null; drawMap(); };
  $('map').onmousemove = hover;
  $('map').onmouseleave = () => { $('tip').hidden = true; };
  $('map').onclick = openCell;
  $('query-form').onsubmit = runQuery;
  $('query-clear').onclick = () => { $('query').value = ''; state.mask = null; $('query-result').textContent = ''; render(); };
  start();
});

// For tests and the console: the palette, cell geometry and what is shown.
window.dashboard = { state, colorOf, cellCenter, openSweep, showCell, itemOf };
