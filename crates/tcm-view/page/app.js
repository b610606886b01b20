// The viewer's page. It holds one row per node as the server's fold of the trace has it (the
// snapshot of docs/viewer.md, then, with each record, the rows that record changed), draws only
// the rows in sight, and asks the server for the rest (a node's details and waits, exceptions,
// counts, the event list). It never reads what a record says happened: a new record kind needs
// no change here. Plain JavaScript, no build.
'use strict';

const ROW = 20;
const FACETS = ['handling', 'expansion', 'execution'];
const POINTS = ['enabled', 'active', 'completed'];
const M_SPAWNED = 0, M_TERMINATING = 10, M_TERMINATED = 11, M_RECLAIMED = 12, M_DEAD = 13, M_RESERVED = 14, M_FAILED = 15, M_SKIPPED = 16;
// Marks per row: the snapshot's `marks` (a newer server may send more than the page reads).
let MARKS = 16;
const mPoint = (f, p) => 1 + 3 * f + p;
// A monitor with more activations than this lists them folded into one row, unless unfolded.
const FOLD_AT = 3;
const KIND_LETTER = { goal: 'G', command: 'C', monitor: 'M', handler: 'H', reserved: 'R', root: '·' };
const COLOURS = {};
for (const s of ['disabled', 'enabled', 'active', 'completed', 'failed']) {
  COLOURS[s] = getComputedStyle(document.documentElement).getPropertyValue('--' + s).trim();
}

const $ = (id) => document.getElementById(id);
const el = (tag, attrs, ...kids) => {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === 'class') e.className = v; else if (k.startsWith('on')) e[k] = v; else e.setAttribute(k, v);
  }
  for (const k of kids) if (k != null) e.append(k);
  return e;
};
const secs = (ns) => (ns / 1e9).toFixed(3) + ' s';

// --- The run's state -------------------------------------------------------------------------
const S = {
  runId: null, ws: null, retry: 0,
  nodes: [],          // by number: {n, p, k, name, m: marks, kids: []}
  times: [],          // flat [seq, t, seq, t, …] at each change of time
  records: 0, finished: false, problem: null,
  cursor: 0, follow: true,
  view: [0, 1],       // time range shown, ns
  collapsed: new Set(), selected: null,
  folds: new Map(),   // monitor number → folded (true) or not, as the user chose
  groups: new Map(),  // monitor number → its activations listed under its folded row, at the cursor
  query: '', matches: [], matchIdx: -1,
  rows: [],           // node numbers in display order
  states: [],         // state variables, as declared: {name, ty, ch: [seq, value, seq, value, …]}
  dirty: true,
};

function reset() {
  S.nodes = []; S.times = []; S.states = []; S.records = 0; S.finished = false; S.problem = null;
  S.cursor = 0; S.follow = true; S.collapsed = new Set(); S.folds = new Map(); S.dirty = true;
}

// One row of the server's fold: [number, parent, kind, name, marks…, agent?, monitor?]
// (docs/viewer.md); `of` is the monitor of an activation, -1 for another node.
function rowNode(r) {
  const of = r[5 + MARKS];
  return { n: r[0], p: r[1], k: r[2], name: r[3], m: r.slice(4, 4 + MARKS), kids: [], agent: r[4 + MARKS] || null, of: typeof of === 'number' ? of : -1 };
}

function loadSnapshot(s) {
  if (typeof s.marks === 'number') MARKS = s.marks;
  S.nodes = [];
  for (const r of s.nodes) S.nodes[r[0]] = rowNode(r);
  for (const node of S.nodes) if (node && node.p >= 0 && S.nodes[node.p]) S.nodes[node.p].kids.push(node.n);
  S.times = s.times; S.records = s.records;
  S.states = (s.states || []).map((v) => ({ name: v.name, ty: v.ty, ch: v.changes })); S.finished = s.finished; S.problem = s.problem;
  const last = lastT();
  fromAddress(s);
  if (S.follow) S.cursor = Math.max(0, S.records - 1);
  if (S.view[1] <= 1 || S.follow) S.view = [0, Math.max(last, 1)];
  S.dirty = true;
  steerState(s); // steer.js: whether the run can be steered, paused, held nodes
}

// The rows a record changed, as the fold has them after it: each replaces the page's node; a node
// new to its parent is added to the parent's children, after those it has (the snapshot's order).
function putRows(rows) {
  for (const r of rows) {
    const node = rowNode(r), was = S.nodes[node.n];
    if (was) node.kids = was.kids;
    S.nodes[node.n] = node;
    if (was && was.p === node.p) continue;
    if (was && S.nodes[was.p]) S.nodes[was.p].kids = S.nodes[was.p].kids.filter((k) => k !== node.n);
    if (node.p >= 0 && S.nodes[node.p]) S.nodes[node.p].kids.push(node.n);
  }
}

// One live message: a record (docs/trace-format.md), the next one, with the rows it changed.
function apply(m) {
  const r = m.record;
  if (r.seq !== S.records) { resync(); return; }
  putRows(m.rows);
  // The state variable the record declared or changed (the server's fold says which).
  if (m.state) {
    let lane = S.states.find((v) => v.name === m.state.name);
    if (!lane) { lane = { name: m.state.name, ty: m.state.ty, ch: [] }; S.states.push(lane); }
    lane.ch.push(r.seq, m.state.value);
  }
  const tl = S.times.length;
  if (tl === 0 || S.times[tl - 1] !== r.t) S.times.push(r.seq, r.t);
  S.records = r.seq + 1;
  if (S.follow) { S.cursor = S.records - 1; if (r.t > S.view[1]) S.view[1] = r.t; }
  S.dirty = true;
  steerState(m); // steer.js
}

function lastT() { return S.times.length ? S.times[S.times.length - 1] : 0; }
// Time of record `seq`.
function tOf(seq) {
  let lo = 0, hi = S.times.length / 2;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (S.times[2 * mid] <= seq) lo = mid + 1; else hi = mid; }
  return lo === 0 ? 0 : S.times[2 * (lo - 1) + 1];
}
// The last record at or before time t.
function seqAt(t) {
  let lo = 0, hi = S.times.length / 2;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (S.times[2 * mid + 1] <= t) lo = mid + 1; else hi = mid; }
  if (lo === 0) return 0;
  if (lo === S.times.length / 2) return Math.max(0, S.records - 1);
  return Math.max(0, S.times[2 * lo] - 1);
}
const reached = (node, i, seq) => node.m[i] >= 0 && node.m[i] <= seq;
function stateAt(node, f, seq) {
  for (let p = 2; p >= 0; p--) if (reached(node, mPoint(f, p), seq)) return POINTS[p];
  return 'disabled';
}

// A state variable's value after record `seq` and the record that gave it it (`undefined` before
// its declaration).
function valueAt(lane, seq) {
  let lo = 0, hi = lane.ch.length / 2;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (lane.ch[2 * mid] <= seq) lo = mid + 1; else hi = mid; }
  return lo === 0 ? undefined : { v: lane.ch[2 * lo - 1], seq: lane.ch[2 * lo - 2] };
}
// A value as TDL writes it: unknown, true, 42, 1.5 (a float always with a fraction), "text".
function fmtValue(v, ty) {
  if (v === null || v === undefined) return 'unknown';
  if (ty === 'float' && Number.isInteger(v)) return v.toFixed(1);
  if (typeof v === 'string') return JSON.stringify(v);
  return String(v);
}

// --- Rows in display order ------------------------------------------------------------------
function pathOf(n) {
  const names = [];
  let node = S.nodes[n], guard = 0;
  while (node && node.n !== 0 && guard++ < 10000) { names.push(node.name); node = S.nodes[node.p]; }
  return names.reverse().join('/');
}

function computeRows() {
  const onlyAlive = $('alive').checked;
  const seq = S.cursor;
  const q = S.query.toLowerCase();
  // Part of a name; with a `/`, part of a path (names from the root's child down, joined by `/`).
  const byPath = q.includes('/');
  let keep = null;
  S.matches = [];
  if (q) {
    keep = new Set();
    for (const node of S.nodes) {
      if (!node || node.n === 0) continue;
      if ((byPath ? pathOf(node.n) : node.name).toLowerCase().includes(q)) {
        S.matches.push(node.n);
        let a = node, guard = 0;
        while (a && !keep.has(a.n) && guard++ < 10000) { keep.add(a.n); a = S.nodes[a.p]; }
      }
    }
    $('matches').textContent = S.matches.length + ' match' + (S.matches.length === 1 ? '' : 'es');
  } else {
    $('matches').textContent = '';
  }
  // Whether node n has a row at the cursor (the group row of folded activations aside).
  const listed = (n) => {
    const node = S.nodes[n];
    if (!node) return false;
    if (node.m[M_SPAWNED] < 0 && node.m[M_DEAD] < 0 && !reached(node, M_RESERVED, seq)) return false;
    if (onlyAlive && (!reached(node, M_SPAWNED, seq) || reached(node, M_RECLAIMED, seq))) return false;
    return !keep || keep.has(n);
  };
  const rows = [];
  S.groups = new Map();
  // The stack holds [n, depth] for a node, [-1 - monitor, depth] for a monitor's group row.
  const stack = [];
  const pushKids = (node, depth) => {
    let kids = node.kids;
    if (node.k === 'monitor') {
      const acts = kids.filter((k) => S.nodes[k] && S.nodes[k].of === node.n);
      if (acts.length > FOLD_AT) {
        const shown = acts.filter(listed);
        const first = acts[0];
        kids = [];
        for (const k of node.kids) {
          if (k === first && shown.length) kids.push(-1 - node.n);
          if (!S.nodes[k] || S.nodes[k].of !== node.n) kids.push(k);
        }
        S.groups.set(node.n, shown);
      }
    }
    for (let i = kids.length - 1; i >= 0; i--) stack.push([kids[i], depth]);
  };
  const root = S.nodes[0];
  if (root) pushKids(root, 0);
  while (stack.length) {
    const [n, depth] = stack.pop();
    if (n < 0) {
      const monitor = -1 - n;
      rows.push(n, depth);
      // A search that matches an activation shows the activations it kept.
      if (!folded(monitor) || keep) {
        const shown = S.groups.get(monitor);
        for (let i = shown.length - 1; i >= 0; i--) stack.push([shown[i], depth + 1]);
      }
      continue;
    }
    const node = S.nodes[n];
    if (!listed(n)) continue;
    rows.push(n, depth);
    if (!S.collapsed.has(n)) pushKids(node, depth + 1);
  }
  S.rows = rows;
  $('spacer').style.height = (rows.length / 2) * ROW + 'px';
}

// Whether a monitor's activations are folded into one row: as the user chose, else folded.
function folded(monitor) {
  return S.folds.has(monitor) ? S.folds.get(monitor) : true;
}

// Unfolds and expands what hides node n's row: its ancestors, and the groups of activations it
// or an ancestor is in.
function showPath(n) {
  let a = S.nodes[n], guard = 0;
  while (a && guard++ < 10000) {
    if (a.n !== n) S.collapsed.delete(a.n);
    if (a.of >= 0) S.folds.set(a.of, false);
    a = S.nodes[a.p];
  }
}

// --- Drawing --------------------------------------------------------------------------------
const pool = [];
function render() {
  if (!S.dirty) return;
  S.dirty = false;
  computeRows();
  const box = $('rows');
  const first = Math.floor(box.scrollTop / ROW);
  const count = Math.ceil(box.clientHeight / ROW) + 1;
  const shift = -(box.scrollTop % ROW);
  const tree = $('tree');
  while (pool.length < count) { const d = el('div', { class: 'row' }); tree.append(d); pool.push(d); }
  const seq = S.cursor;
  const matchSet = S.query ? new Set(S.matches) : null;
  for (let i = 0; i < pool.length; i++) {
    const d = pool[i];
    const idx = first + i;
    if (i >= count || idx * 2 >= S.rows.length) { d.hidden = true; continue; }
    d.hidden = false;
    const n = S.rows[idx * 2], depth = S.rows[idx * 2 + 1];
    d.style.top = (shift + i * ROW) + 'px';
    if (n < 0) { groupRow(d, -1 - n, depth, seq); continue; }
    delete d.dataset.group;
    d.title = '';
    const node = S.nodes[n];
    d.dataset.n = n;
    const states = [0, 1, 2].map((f) => stateAt(node, f, seq));
    d.dataset.h = states[0]; d.dataset.x = states[1]; d.dataset.e = states[2];
    const spawned = reached(node, M_SPAWNED, seq);
    const failed = reached(node, M_FAILED, seq);
    const skipped = reached(node, M_SKIPPED, seq);
    d.className = 'row' + (n === S.selected ? ' sel' : '') + (spawned ? '' : ' future')
      + (reached(node, M_RECLAIMED, seq) ? ' gone' : '')
      + (reached(node, M_TERMINATING, seq) ? ' terminated' : '')
      + (failed ? ' failed' : '') + (skipped ? ' skipped' : '') + (matchSet && matchSet.has(n) ? ' match' : '');
    const tog = node.kids.length ? (S.collapsed.has(n) ? '▸' : '▾') : '';
    d.replaceChildren(
      el('span', { style: 'display:inline-block;width:' + (depth * 14) + 'px' }),
      el('span', { class: 'tog' }, tog),
      el('span', { class: 'kind k-' + node.k, title: node.k }, KIND_LETTER[node.k] || '?'),
      ...states.map((s, f) => el('span', { class: 'sq s-' + (f === 0 && s === 'completed' ? (failed ? 'failed' : skipped ? 'skipped' : s) : s), title: FACETS[f] + ': ' + (f === 0 && skipped ? 'skipped' : s) })),
      el('span', { class: 'name' }, node.name),
      el('span', { class: 'num' }, '{' + n + '}'),
      ...(skipped ? [el('span', { class: 'tag', title: 'its skip condition held when its turn came: it completed without running' }, 'skipped')] : []),
      ...(node.agent ? [el('span', { class: 'agent', title: 'runs on agent ' + node.agent }, '@' + node.agent)] : []),
    );
  }
  drawBars(first, count, shift);
  drawAxis();
  drawStates();
  const t = tOf(seq);
  $('cursor').max = Math.max(0, S.records - 1);
  $('cursor').value = seq;
  $('cursorlabel').textContent = 'record ' + seq + ' of ' + S.records + ' · t = ' + secs(t);
  const pb = $('problem');
  pb.hidden = !S.problem;
  pb.textContent = S.problem ? 'This trace could not be read to its end; everything before is shown.\n' + S.problem : '';
}

// The row of a monitor's activations folded into one: the last one's kind and states at the
// cursor, its name, and how many there are by the cursor; a click lists them, or folds them again.
function groupRow(d, monitor, depth, seq) {
  const shown = S.groups.get(monitor);
  const made = shown.filter((a) => reached(S.nodes[a], M_SPAWNED, seq));
  const last = S.nodes[made.length ? made[made.length - 1] : shown[0]];
  const open = !folded(monitor) || !!S.query;
  const states = [0, 1, 2].map((f) => stateAt(last, f, seq));
  const failed = reached(last, M_FAILED, seq);
  d.dataset.n = '';
  d.dataset.group = monitor;
  delete d.dataset.h; delete d.dataset.x; delete d.dataset.e;
  d.className = 'row group' + (reached(last, M_SPAWNED, seq) ? '' : ' future') + (reached(last, M_RECLAIMED, seq) ? ' gone' : '');
  const what = made.length + ' activation' + (made.length === 1 ? '' : 's') + ' of ' + S.nodes[monitor].name + ' {' + monitor + '} by the cursor'
    + (made.length < shown.length ? ', ' + shown.length + ' in all' : '');
  d.title = what + (open ? ': click to fold them into this row' : ': click to list them');
  d.replaceChildren(
    el('span', { style: 'display:inline-block;width:' + (depth * 14) + 'px' }),
    el('span', { class: 'tog' }, open ? '▾' : '▸'),
    el('span', { class: 'kind k-' + last.k, title: last.k }, KIND_LETTER[last.k] || '?'),
    ...states.map((s, f) => el('span', { class: 'sq s-' + (failed && f === 0 && s === 'completed' ? 'failed' : s), title: 'the last one\'s ' + FACETS[f] + ': ' + s })),
    el('span', { class: 'name' }, last.name),
    el('span', { class: 'count', title: what }, '×' + made.length),
  );
}

function fitCanvas(c) {
  const r = c.getBoundingClientRect();
  const dpr = window.devicePixelRatio || 1;
  if (c.width !== Math.round(r.width * dpr) || c.height !== Math.round(r.height * dpr)) {
    c.width = Math.round(r.width * dpr); c.height = Math.round(r.height * dpr);
  }
  const g = c.getContext('2d');
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  return [g, r.width, r.height];
}
const xOf = (t, w) => ((t - S.view[0]) / Math.max(1, S.view[1] - S.view[0])) * w;
const tAtX = (x, w) => S.view[0] + (x / w) * (S.view[1] - S.view[0]);

function drawBars(first, count, shift) {
  const [g, w, h] = fitCanvas($('bars'));
  g.clearRect(0, 0, w, h);
  const seq = S.cursor, end = tOf(seq);
  for (let i = 0; i < count; i++) {
    const idx = first + i;
    if (idx * 2 >= S.rows.length) break;
    const n = S.rows[idx * 2];
    const y = shift + i * ROW;
    if (i % 2) { g.fillStyle = '#fafafa'; g.fillRect(0, y, w, ROW); }
    if (n < 0) {
      // A folded group: every activation's bars on one row.
      for (const a of S.groups.get(-1 - n)) nodeBars(g, S.nodes[a], y, w, seq, end);
    } else {
      nodeBars(g, S.nodes[n], y, w, seq, end);
    }
  }
  g.fillStyle = '#d33b3b';
  g.fillRect(xOf(end, w) - 0.5, 0, 1, h);
}

// One node's bars at height y: per facet, enabled, active and completed up to the cursor.
function nodeBars(g, node, y, w, seq, end) {
  for (let f = 0; f < 3; f++) {
    const e = node.m[mPoint(f, 0)], a = node.m[mPoint(f, 1)], c = node.m[mPoint(f, 2)];
    const yy = y + 3 + f * 5;
    const te = e >= 0 && e <= seq ? tOf(e) : null;
    const ta = a >= 0 && a <= seq ? tOf(a) : null;
    const tc = c >= 0 && c <= seq ? tOf(c) : null;
    if (te !== null) {
      g.fillStyle = COLOURS.enabled;
      const stop = ta !== null ? ta : tc !== null ? tc : end;
      g.fillRect(xOf(te, w), yy, Math.max(1, xOf(stop, w) - xOf(te, w)), 4);
    }
    if (ta !== null) {
      g.fillStyle = f === 0 && reached(node, M_FAILED, seq) ? COLOURS.failed : COLOURS.active;
      const stop = tc !== null ? tc : end;
      g.fillRect(xOf(ta, w), yy, Math.max(2, xOf(stop, w) - xOf(ta, w)), 4);
    }
    if (tc !== null) {
      g.fillStyle = f === 0 && reached(node, M_SKIPPED, seq) ? COLOURS.disabled : COLOURS.completed;
      g.fillRect(xOf(tc, w) - 1, yy, 2, 4);
    }
  }
  if (reached(node, M_TERMINATING, seq)) {
    g.fillStyle = '#333';
    g.fillRect(xOf(tOf(node.m[M_TERMINATING]), w) - 1, y + 2, 2, ROW - 4);
  }
}

function drawAxis() {
  const [g, w, h] = fitCanvas($('axis'));
  g.clearRect(0, 0, w, h);
  const span = Math.max(1, S.view[1] - S.view[0]);
  const raw = span / 8;
  const pow = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((k) => k * pow).find((s) => s >= raw) || raw;
  g.fillStyle = '#777'; g.font = '11px system-ui';
  for (let t = Math.ceil(S.view[0] / step) * step; t <= S.view[1]; t += step) {
    const x = xOf(t, w);
    g.fillRect(x, h - 6, 1, 6);
    g.fillText(secs(t).replace('.000', ''), x + 2, 12);
  }
  g.fillStyle = '#d33b3b';
  g.fillRect(xOf(tOf(S.cursor), w) - 0.5, 0, 1, h);
}

// --- State variables: one lane each under the timeline, on the same time scale -------------
const LANE = 26;
let hatch = null;
function hatchPattern(g) {
  if (!hatch) {
    const c = document.createElement('canvas'); c.width = 6; c.height = 6;
    const h = c.getContext('2d');
    h.strokeStyle = '#b8b8b8'; h.lineWidth = 1.2;
    h.beginPath(); h.moveTo(0, 6); h.lineTo(6, 0); h.stroke();
    hatch = c;
  }
  return g.createPattern(hatch, 'repeat');
}

function drawStates() {
  const box = $('states');
  box.hidden = S.states.length === 0;
  if (box.hidden) return;
  const seq = S.cursor, tc = tOf(seq), end = Math.max(lastT(), S.view[1]);
  // The labels: each variable's value at the cursor, and since when it has it.
  const labels = $('statelabels');
  while (labels.children.length < S.states.length) labels.append(el('div', { class: 'lane' }));
  while (labels.children.length > S.states.length) labels.lastChild.remove();
  S.states.forEach((lane, i) => {
    const d = labels.children[i];
    const at = valueAt(lane, seq);
    const v = at ? at.v : null;
    const cls = at === undefined ? 'v-unknown' : v === null ? 'v-unknown' : v === true ? 'v-true' : v === false ? 'v-false' : '';
    d.dataset.var = lane.name;
    d.title = lane.name + ' (' + lane.ty + ')' + (at ? ' = ' + fmtValue(v, lane.ty) + ' since ' + secs(tOf(at.seq)) : ': not declared yet at the cursor');
    d.replaceChildren(
      el('span', { class: 'vname' }, lane.name), el('span', { class: 'ty' }, lane.ty), ' = ',
      el('span', { class: 'val ' + cls }, at ? fmtValue(v, lane.ty) : 'undeclared'),
      at ? el('span', { class: 'since' }, 'since ' + secs(tOf(at.seq))) : null,
    );
  });
  // The lanes, as wide as the bars above so that times line up.
  const c = $('lanes');
  c.style.width = $('bars').getBoundingClientRect().width + 'px';
  c.style.height = (S.states.length * LANE) + 'px';
  const [g, w, h] = fitCanvas(c);
  g.clearRect(0, 0, w, h);
  g.font = '11px ui-monospace, monospace'; g.textBaseline = 'middle';
  S.states.forEach((lane, i) => {
    const y0 = i * LANE, top = y0 + 5, bot = y0 + LANE - 5, mid = y0 + LANE / 2;
    g.fillStyle = '#f0f0f0'; g.fillRect(0, y0, w, 1);
    const n = lane.ch.length / 2;
    const nums = [];
    for (let j = 0; j < n; j++) if (typeof lane.ch[2 * j + 1] === 'number') nums.push(lane.ch[2 * j + 1]);
    const lo = Math.min(...nums), hi = Math.max(...nums);
    const yNum = (v) => (hi > lo ? bot - ((v - lo) / (hi - lo)) * (bot - top) : mid);
    let prevY = null;
    for (let j = 0; j < n; j++) {
      const v = lane.ch[2 * j + 1];
      const x0 = xOf(tOf(lane.ch[2 * j]), w);
      const x1 = j + 1 < n ? xOf(tOf(lane.ch[2 * j + 2]), w) : xOf(end, w);
      if (x1 < 0 || x0 > w) { prevY = typeof v === 'number' ? yNum(v) : null; continue; }
      const width = Math.max(1, x1 - x0);
      let label = fmtValue(v, lane.ty), ly = mid;
      if (v === null) {
        g.fillStyle = hatchPattern(g); g.fillRect(x0, top, width, bot - top);
        prevY = null;
      } else if (v === true) {
        g.fillStyle = COLOURS.completed; g.fillRect(x0, top, width, bot - top);
      } else if (v === false) {
        g.fillStyle = '#9a9a9a'; g.fillRect(x0, bot - 3, width, 3);
        ly = mid - 2;
      } else if (typeof v === 'number') {
        // A step line between the lane's least and greatest values.
        const y = yNum(v);
        g.strokeStyle = COLOURS.active; g.lineWidth = 2;
        g.beginPath();
        if (prevY !== null) { g.moveTo(x0, prevY); g.lineTo(x0, y); } else g.moveTo(x0, y);
        g.lineTo(x0 + width, y); g.stroke();
        prevY = y; ly = y < mid ? y + 7 : y - 7;
      } else {
        g.strokeStyle = '#8b8bb0'; g.lineWidth = 1; g.strokeRect(x0 + 0.5, top + 0.5, width - 1, bot - top - 1);
      }
      // Each change marked where it happened.
      if (j > 0) { g.fillStyle = '#444'; g.fillRect(x0 - 0.5, y0 + 2, 1, LANE - 4); }
      const tw = g.measureText(label).width;
      if (width > tw + 8) {
        g.fillStyle = v === true ? '#fff' : '#333';
        g.fillText(label, Math.max(x0, 0) + 4, ly);
      }
    }
  });
  // After the cursor, faded; the cursor itself.
  const xc = xOf(tc, w);
  if (xc < w) { g.fillStyle = 'rgba(255,255,255,0.55)'; g.fillRect(Math.max(0, xc), 0, w, h); }
  g.fillStyle = '#d33b3b';
  g.fillRect(xc - 0.5, 0, 1, h);
}

let frame = 0;
function schedule() { S.dirty = true; if (!frame) frame = requestAnimationFrame(() => { frame = 0; render(); }); }

// --- Talking to the server -------------------------------------------------------------------
async function getJSON(path) {
  const r = await fetch(path);
  if (!r.ok) throw new Error(path + ': ' + r.status + ' ' + (await r.text()));
  return r.json();
}

async function loadRuns() {
  try {
    const runs = await getJSON('/api/runs');
    const sel = $('run');
    const had = sel.options.length;
    if (had !== runs.length) {
      sel.replaceChildren(...runs.map((r) => el('option', { value: r.id }, r.id + ': ' + r.name)));
      const fromHash = Number(new URLSearchParams(location.hash.slice(1)).get('run') ?? fromAddress());
      const want = S.runId !== null ? S.runId : (runs.some((r) => r.id === fromHash) ? fromHash : (runs.length ? runs[runs.length - 1].id : null));
      if (want !== null) { sel.value = want; if (S.runId === null) open(want); }
    }
    if (!runs.length) $('status').textContent = 'no run yet';
  } catch (e) {
    $('status').textContent = 'server unreachable';
  }
}

function open(id) {
  // Two lists of runs fetched at once (a slow first one, then the periodic one) both find no
  // run open: the second must not reset the page the first opened.
  if (S.runId === id && S.ws) return;
  if (S.ws) { S.ws.onclose = null; S.ws.close(); }
  S.runId = id; reset(); S.selected = null;
  history.replaceState(null, '', '#run=' + id);
  connect();
}

function connect() {
  const proto = location.protocol === 'https:' ? 'wss:' : 'ws:';
  const ws = new WebSocket(proto + '//' + location.host + '/api/runs/' + S.runId + '/live');
  S.ws = ws;
  $('status').textContent = 'loading…';
  ws.onmessage = (msg) => {
    const m = JSON.parse(msg.data);
    if (m.type === 'snapshot') {
      loadSnapshot(m); S.retry = 0; status(); refreshPanels();
      S.dirty = true; render();
      // When the tree was first shown, ms since navigation (read by the open_million benchmark).
      if (!window.treeShownAt && S.rows.length) window.treeShownAt = performance.now();
    }
    else if (m.type === 'finished') { S.finished = true; status(); refreshPanels(); }
    else if (m.type === 'resync') resync();
    else if (m.type === 'record') { apply(m); status(); }
    schedule();
  };
  ws.onclose = () => {
    if (S.ws !== ws) return;
    $('status').textContent = 'disconnected; reconnecting…';
    $('status').className = '';
    S.retry = Math.min(S.retry + 1, 5);
    setTimeout(() => { if (S.ws === ws) connect(); }, 400 * S.retry);
  };
}

// Out of step with the server: start again from a snapshot.
function resync() { if (S.ws) S.ws.close(); }

function status() {
  const st = $('status');
  st.textContent = (S.finished ? 'finished' : 'live') + ' · ' + S.records + ' records · ' + (S.nodes.length - 1) + ' nodes · ' + secs(lastT());
  st.className = S.finished ? '' : 'live';
}

// --- Panels --------------------------------------------------------------------------------
let panelTimer = 0;
function refreshPanels() {
  clearTimeout(panelTimer);
  panelTimer = setTimeout(() => {
    const tab = document.querySelector('#tabs .on').dataset.tab;
    if (tab === 'node') showNode();
    else if (tab === 'exceptions') showExceptions();
    else if (tab === 'stats') showStats();
    else if (tab === 'log') showLog();
  }, 120);
}

function nodeLink(n, text) {
  return el('a', { class: 'node', 'data-n': n, onclick: () => select(n, true) }, text || (S.nodes[n] ? S.nodes[n].name + ' {' + n + '}' : '{' + n + '}'));
}

function select(n, scroll) {
  S.selected = n;
  showPath(n);
  S.dirty = true; render();
  if (scroll) reveal(n);
  document.querySelector('#tabs [data-tab=node]').click();
}

// Scrolls the tree so that node n's row is in sight (if it is listed), unfolding what hides it.
function reveal(n) {
  showPath(n);
  computeRows();
  for (let i = 0; i < S.rows.length; i += 2) if (S.rows[i] === n) {
    const box = $('rows'), y = (i / 2) * ROW;
    if (y < box.scrollTop || y > box.scrollTop + box.clientHeight - 2 * ROW) box.scrollTop = Math.max(0, y - box.clientHeight / 3);
    break;
  }
  S.dirty = true; render();
}

async function showNode() {
  const tab = $('tab-node');
  if (S.selected === null) { tab.replaceChildren(el('p', { class: 'hint' }, 'Select a node in the tree.')); return; }
  let v;
  try { v = await getJSON('/api/runs/' + S.runId + '/node/' + S.selected + '?at=' + S.cursor); }
  catch (e) { tab.replaceChildren(el('p', { class: 'hint' }, String(e))); return; }
  const kv = el('dl', { class: 'kv' });
  const add = (k, val) => { if (val !== null && val !== undefined && val !== '') kv.append(el('dt', {}, k), el('dd', {}, val)); };
  add('path', v.path);
  add('kind', v.kind);
  add('arguments', v.args);
  add('at the cursor', v.life + ' · ' + FACETS.map((f, i) => f + ' ' + v.states[i]).join(', '));
  if (v.parent !== null) add('parent', nodeLink(v.parent));
  if (v.handles) add('handles', el('span', {}, v.handles[1] + ' for ', nodeLink(v.handles[0])));
  if (v.retry_of !== null) add('retry of', nodeLink(v.retry_of));
  add('runs on agent', v.agent);
  if (v.queued_ns !== null) add('enabled → active', secs(v.queued_ns));
  if (v.ran_ns !== null) add('action ran', secs(v.ran_ns));
  if (v.kind === 'monitor') add('activations · triggers', v.activations + ' · ' + v.triggers_count);
  add('children', String(v.children.length));
  add('paused', v.paused);
  const parts = [el('h3', {}, v.name + ' {' + v.node + '}'), kv];
  parts.push(el('h3', {}, 'Waiting on'));
  if (v.waits.length) {
    parts.push(el('ul', { class: 'waits', id: 'waits' }, ...v.waits.map((w) => el('li', {},
      el('span', { class: 'facet' }, w.facet), ': ',
      w.event ? el('span', {}, w.what, ' · ', nodeLink(w.event.node, 'go to {' + w.event.node + '}')) : w.what,
      el('span', { class: 'hint' }, ' — since ' + secs(w.since))))));
  } else {
    parts.push(el('p', { class: 'hint', id: 'waits' }, v.life === 'not yet spawned' ? 'Not spawned yet at the cursor.' : 'Nothing holds it back at the cursor.'));
  }
  if (v.conditions.length) {
    parts.push(el('h3', {}, 'Conditions'), el('ul', { class: 'conds', id: 'conds' }, ...v.conditions.map((c) => el('li', {},
      el('code', {}, c.form + ' ' + c.condition), ' is ', el('b', {}, c.value), ': ' + c.state,
      c.reads.length ? el('span', { class: 'reads' }, c.reads.map((r) => r.name + ' = ' + r.value + (r.since !== null ? ' since ' + secs(r.since) : '')).join(', ')) : null))));
  }
  if (v.triggers.length) parts.push(el('h3', {}, 'Triggers'), el('ul', {}, ...v.triggers.map((t) => el('li', {}, t))));
  if (v.failures.length) parts.push(el('h3', {}, 'Failures'), el('ul', {}, ...v.failures.map(([f, t]) => el('li', {}, secs(t) + ' ' + f))));
  if (v.logs.length) parts.push(el('h3', {}, 'Log'), el('ul', { id: 'logs' }, ...v.logs.map(([line, t]) => el('li', {}, secs(t) + ' ' + line))));
  parts.push(el('h3', {}, 'History'), el('table', {}, ...v.history.map(([what, t]) => el('tr', {}, el('td', {}, secs(t)), el('td', {}, what)))));
  tab.replaceChildren(...parts);
  steerNode(tab); // steer.js: the node's steering buttons, when the page steers the run
}

async function showExceptions() {
  const tab = $('tab-exceptions');
  const list = await getJSON('/api/runs/' + S.runId + '/exceptions');
  if (!list.length) { tab.replaceChildren(el('p', { class: 'hint' }, 'No exception was raised.')); return; }
  tab.replaceChildren(...list.map((x) => el('div', { class: 'exc' },
    el('div', {}, secs(x.at.t) + ' ', el('b', {}, x.exception), ' raised by ', nodeLink(x.node, x.path + ' {' + x.node + '}'), ': ' + x.message),
    el('ol', { class: 'steps' }, ...(x.steps.length ? x.steps : [{ what: 'pending', detail: 'no handler chosen yet', node: null, at: x.at }]).map((s) => el('li', {},
      ...(s.what === 'chosen' ? [secs(s.at.t) + ' handler ', el('b', {}, s.detail), ' chosen, run as ', nodeLink(s.node)]
        : s.what === 'retried' ? [secs(s.at.t) + ' retried as ', nodeLink(s.node)]
        : s.what === 'taken' ? [secs(s.at.t) + ' taken by its parent ', nodeLink(s.node), ', which ' + s.detail]
        : [secs(s.at.t) + ' ' + s.what + ' ', s.node !== null ? nodeLink(s.node) : '', s.detail ? ' ' + s.detail : ''])))))));
}

async function showStats() {
  const tab = $('tab-stats');
  const list = await getJSON('/api/runs/' + S.runId + '/stats');
  const head = el('tr', {}, ...['task', 'kind', 'nodes', 'ok', 'skipped', 'failed', 'terminated', 'open', 'mean', 'max', 'total'].map((h) => el('th', {}, h)));
  tab.replaceChildren(el('table', {}, head, ...list.map((s) => el('tr', {},
    el('td', {}, el('a', { class: 'node', onclick: () => { $('search').value = s.name; search(); } }, s.name)),
    el('td', {}, s.kind), el('td', {}, s.count), el('td', {}, s.succeeded), el('td', {}, s.skipped), el('td', {}, s.failed),
    el('td', {}, s.terminated), el('td', {}, s.unfinished),
    el('td', {}, s.ran ? secs(s.mean_ns) : ''), el('td', {}, s.ran ? secs(s.max_ns) : ''), el('td', {}, s.ran ? secs(s.total_ns) : '')))));
}

// The run's log: the lines bodies wrote (`log` records), each with its time and node; those after
// the cursor are dimmed. A line moves the cursor to it; its node's name selects the node.
const LOG_LINES = 2000;
async function showLog() {
  const tab = $('tab-log');
  const p = new URLSearchParams({ name: '"ev":"log"', offset: 0, limit: LOG_LINES });
  const r = await getJSON('/api/runs/' + S.runId + '/events?' + p);
  if (!r.total) { tab.replaceChildren(el('p', { class: 'hint' }, 'No body wrote a log line (TDL\'s log statement).')); return; }
  const lines = r.records.map((rec) => el('li', {
    'data-seq': rec.seq, class: rec.seq > S.cursor ? 'later' : '', title: 'record ' + rec.seq + ': move the cursor here',
    onclick: () => setCursor(rec.seq),
  }, secs(rec.t) + ' ', nodeLink(rec.node), ': ' + rec.message));
  const more = r.total > r.records.length
    ? [el('p', { class: 'hint' }, 'The first ' + r.records.length + ' of ' + r.total + ' lines; the Events tab pages through them all (filter "ev":"log").')]
    : [];
  tab.replaceChildren(...more, el('ol', { id: 'loglist' }, ...lines));
}

let evOffset = 0, evAsked = 0;
async function showEvents() {
  const p = new URLSearchParams();
  if ($('evname').value) p.set('name', $('evname').value);
  const toNs = (v) => String(Math.round(parseFloat(v) * 1e9));
  if ($('evfrom').value && !isNaN(parseFloat($('evfrom').value))) p.set('from', toNs($('evfrom').value));
  if ($('evto').value && !isNaN(parseFloat($('evto').value))) p.set('to', toNs($('evto').value));
  if ($('evnode').checked && S.selected !== null) p.set('node', S.selected);
  p.set('offset', evOffset); p.set('limit', 200);
  const asked = ++evAsked;
  const r = await getJSON('/api/runs/' + S.runId + '/events?' + p);
  if (asked !== evAsked) return; // a later filter was asked for meanwhile
  $('evcount').textContent = r.total ? (r.offset + 1) + '–' + (r.offset + r.records.length) + ' of ' + r.total : 'no record matches';
  $('evlist').replaceChildren(...r.records.map((rec) => {
    const rest = Object.assign({}, rec);
    delete rest.seq; delete rest.t; delete rest.ev;
    const nm = typeof rec.node === 'number' && S.nodes[rec.node] ? ' ' + S.nodes[rec.node].name : '';
    return el('li', {
      'data-seq': rec.seq, title: 'record ' + rec.seq + ': move the cursor here',
      onclick: () => { setCursor(rec.seq); if (typeof rec.node === 'number') select(rec.node, true); },
    }, '#' + rec.seq + ' ' + secs(rec.t) + ' ' + rec.ev + nm + ' ' + JSON.stringify(rest));
  }));
}

function setCursor(seq) {
  S.cursor = Math.max(0, Math.min(seq, S.records - 1));
  S.follow = S.cursor === S.records - 1 && !S.finished;
  schedule(); refreshPanels();
}

function search() {
  S.query = $('search').value.trim();
  S.matchIdx = -1;
  schedule();
}

// --- Wiring --------------------------------------------------------------------------------
$('run').onchange = () => open(Number($('run').value));
let searchTimer = 0;
$('search').oninput = () => { clearTimeout(searchTimer); searchTimer = setTimeout(search, 150); };
$('search').onkeydown = (e) => {
  if (e.key === 'Enter' && S.matches.length) {
    S.matchIdx = (S.matchIdx + 1) % S.matches.length;
    select(S.matches[S.matchIdx], true);
  }
};
$('cursor').oninput = () => setCursor(Number($('cursor').value));
$('alive').onchange = schedule;
$('rows').onscroll = () => { S.dirty = true; render(); };
window.onresize = schedule;
$('tree').onclick = (e) => {
  const row = e.target.closest('.row');
  if (!row) return;
  if (row.dataset.group) {
    const monitor = Number(row.dataset.group);
    S.folds.set(monitor, !folded(monitor));
    schedule(); return;
  }
  const n = Number(row.dataset.n);
  if (e.target.classList.contains('tog')) {
    if (S.collapsed.has(n)) S.collapsed.delete(n); else S.collapsed.add(n);
    schedule(); return;
  }
  select(n, false);
};
const zoom = (k, tCentre) => {
  const [a, b] = S.view;
  const c = tCentre === undefined ? (a + b) / 2 : tCentre;
  const span = Math.max(1000, (b - a) * k);
  S.view = [Math.max(0, c - (c - a) * k), 0]; S.view[1] = S.view[0] + span;
  schedule();
};
$('zoomin').onclick = () => zoom(0.5, tOf(S.cursor));
$('zoomout').onclick = () => zoom(2, tOf(S.cursor));
$('fit').onclick = () => { S.view = [0, Math.max(1, lastT())]; schedule(); };
let drag = null;
const bars = $('bars');
bars.onwheel = (e) => {
  e.preventDefault();
  const r = bars.getBoundingClientRect();
  zoom(e.deltaY > 0 ? 1.25 : 0.8, tAtX(e.clientX - r.left, r.width));
};
bars.onmousedown = (e) => { drag = { x: e.clientX, view: S.view.slice(), moved: false }; };
window.onmousemove = (e) => {
  if (!drag) return;
  const dx = e.clientX - drag.x;
  if (Math.abs(dx) > 3) drag.moved = true;
  if (drag.moved) {
    const w = bars.getBoundingClientRect().width;
    const dt = (dx / w) * (drag.view[1] - drag.view[0]);
    S.view = [drag.view[0] - dt, drag.view[1] - dt];
    schedule();
  }
};
window.onmouseup = (e) => {
  if (drag && !drag.moved && e.target === bars) {
    const r = bars.getBoundingClientRect();
    setCursor(seqAt(tAtX(e.clientX - r.left, r.width)));
    const i = Math.floor((e.clientY - r.top + $('rows').scrollTop % ROW) / ROW) + Math.floor($('rows').scrollTop / ROW);
    if (i * 2 < S.rows.length && S.rows[i * 2] >= 0) select(S.rows[i * 2], false);
  }
  drag = null;
};
$('lanes').onclick = (e) => {
  const r = $('lanes').getBoundingClientRect();
  setCursor(seqAt(tAtX(e.clientX - r.left, r.width)));
};
for (const b of document.querySelectorAll('#tabs button')) {
  b.onclick = () => {
    for (const o of document.querySelectorAll('#tabs button')) o.classList.toggle('on', o === b);
    for (const t of document.querySelectorAll('.tab')) t.hidden = t.id !== 'tab-' + b.dataset.tab;
    if (b.dataset.tab === 'events') showEvents(); else refreshPanels();
  };
}
$('evfilter').onsubmit = (e) => { e.preventDefault(); evOffset = 0; showEvents(); };
$('evprev').onclick = () => { evOffset = Math.max(0, evOffset - 200); showEvents(); };
$('evnext').onclick = () => { evOffset += 200; showEvents(); };

// What the page's address asks for, `?run=N&at=SEQ` (what `tdl view --at` prints; docs/viewer.md):
// without a snapshot, the run to open (null if none; a `#run=` the page wrote since, the run last
// chosen, comes first); with the first snapshot of that run (of any run without `run`), it puts
// the cursor on record SEQ (the last if there are fewer), where it stays rather than follow the
// live tail. Once only: a run opened again later opens as any other.
let addressUsed = false;
function fromAddress(s) {
  const q = new URLSearchParams(location.search);
  const num = (k) => (/^[0-9]+$/.test(q.get(k) || '') ? Number(q.get(k)) : null);
  const run = num('run'), at = num('at');
  if (!s || addressUsed || at === null || (run !== null && run !== S.runId)) return run;
  addressUsed = true;
  S.cursor = Math.max(0, Math.min(at, s.records - 1));
  S.follow = false;
  return run;
}

loadRuns();
setInterval(loadRuns, 2000);
