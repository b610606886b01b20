// Steering a live run from the page (docs/viewer.md, "Steering a run"). Loaded after app.js, whose
// state (S) and helpers ($, el, select) it uses; app.js calls steerState with each snapshot and
// live record (their `control`, `paused` and `held`, from the server's fold) and steerNode when
// it shows a node's details. The run's token comes in the page's address (?run=ID&token=…), is
// kept in this script's variable and sent in the header x-tdl-token with each request; without
// it nothing here is shown but the paused banner. While it steers, the page sends a heartbeat
// every second: a run whose page goes silent is released by the server.
'use strict';

const CTL = (() => {
  const q = new URLSearchParams(location.search);
  return {
    token: q.get('token'), run: Number(q.get('run') || 0),
    control: false, paused: null, held: [],
    rules: [],          // rules made from this page: {id, what}, until removed
    nodeKey: '',
  };
})();

// Whether this page steers the run it shows.
function steering() {
  return !!CTL.token && CTL.control && S.runId === CTL.run && !S.finished;
}

function say(text, bad) {
  const m = $('ctl-msg');
  m.textContent = text;
  m.className = bad ? 'bad' : '';
}

// Sends one control request; its answer, or null (the reason shown in the bar).
async function ctl(op) {
  try {
    const r = await fetch('/api/runs/' + CTL.run + '/control', {
      method: 'POST',
      headers: { 'content-type': 'application/json', 'x-tdl-token': CTL.token },
      body: JSON.stringify(op),
    });
    const text = await r.text();
    if (!r.ok) { say(op.op + ': ' + text, true); return null; }
    const a = JSON.parse(text);
    if (op.op !== 'heartbeat') say(op.op + (a.id !== undefined ? ' #' + a.id : '') + (a.changed === false ? ': nothing to do' : ': done'), false);
    if (a.id !== undefined) { CTL.rules.push({ id: a.id, what: ruleText(op) }); drawRules(); }
    if (op.op === 'remove') { CTL.rules = CTL.rules.filter((r) => r.id !== op.id); drawRules(); }
    return a;
  } catch (e) {
    say(op.op + ': ' + e, true);
    return null;
  }
}

// A rule as the bar lists it.
function ruleText(op) {
  const on = op.task !== undefined ? op.task : op.path !== undefined ? op.path : op.node !== undefined ? '{' + op.node + '}' : op.exception;
  if (op.op === 'break') return 'break ' + ({ start: 'before', end: 'after', raised: 'on an exception of', handler: 'on a handler for' })[op.at] + ' ' + on;
  if (op.op === 'inject') return 'inject ' + (op.never ? 'never ends' : op.exception) + ' into ' + on;
  return 'approval for ' + on;
}

// The rules made from this page (a release by the server may have cleared them meanwhile: its
// `control` record says so), each with a button that removes it.
function drawRules() {
  $('ctl-rules').replaceChildren(...CTL.rules.map((r) => el('span', { class: 'ctl-rule' }, '#' + r.id + ' ' + r.what,
    el('button', { 'data-ctl': 'remove', 'data-id': r.id, title: 'remove rule #' + r.id, onclick: () => ctl({ op: 'remove', id: r.id }) }, '×'))));
}

// The steering state of a snapshot or a live record.
function steerState(m) {
  if ('control' in m) {
    CTL.control = !!m.control;
    CTL.paused = m.paused === undefined ? null : m.paused;
    CTL.held = m.held || [];
  }
  steerDraw();
}

function steerDraw() {
  const on = steering();
  $('steerbar').hidden = !on;
  const banner = $('ctl-banner');
  const paused = CTL.paused !== null && S.runId === CTL.run && !S.finished;
  banner.hidden = !paused;
  banner.textContent = paused ? 'paused: ' + CTL.paused : '';
  const held = $('ctl-held');
  held.replaceChildren(...(CTL.held.length ? ['held for approval: ', ...CTL.held.map((n) => nodeLink(n))] : []));
  steerNodeDraw();
}

// The node tab's steering section, under the node's facts: app.js built the tab for a node.
function steerNode(tab) {
  CTL.nodeKey = '';
  const box = el('div', { id: 'ctl-node', hidden: '' });
  const facts = tab.querySelector('dl.kv');
  if (facts) facts.after(box); else tab.append(box);
  steerNodeDraw();
}

// Draws the selected node's buttons again when what they depend on changed (so a field being
// typed in survives the records that change nothing here).
function steerNodeDraw() {
  const box = $('ctl-node');
  if (!box) return;
  const n = S.selected, node = n === null ? null : S.nodes[n];
  const on = steering() && !!node && n !== 0;
  const held = on && CTL.held.includes(n);
  const key = on + '|' + n + '|' + held;
  if (key === CTL.nodeKey) return;
  CTL.nodeKey = key;
  box.hidden = !on;
  if (!on) { box.replaceChildren(); return; }
  const name = node.name;
  const button = (what, text, title, op) => el('button', { 'data-ctl': what, title, onclick: () => { const o = op(); if (o) ctl(o); } }, text);
  const exception = el('input', { 'data-ctl': 'inject-exception', placeholder: 'exception, e.g. Blocked', size: 18 });
  const inject = el('span', { class: 'ctl-inject', hidden: '' }, exception, ' ',
    button('inject-go', 'Inject', 'the next node of ' + name + ' to start fails with this exception instead of running', () => {
      const e = exception.value.trim();
      if (!e) { say('inject: name the exception', true); return null; }
      return { op: 'inject', task: name, exception: e, message: 'injected from the viewer' };
    }));
  const reason = el('input', { 'data-ctl': 'refuse-reason', placeholder: 'reason', size: 14 });
  box.replaceChildren(
    el('h3', {}, 'Steer'),
    el('div', { class: 'ctl-row' },
      button('break-start', 'Break before start', 'pause the run before each node of ' + name + ' starts', () => ({ op: 'break', at: 'start', task: name })),
      button('break-end', 'Break after end', 'pause the run after the action of each node of ' + name + ' ended', () => ({ op: 'break', at: 'end', task: name })),
      el('button', { 'data-ctl': 'inject', title: 'make the next node of ' + name + ' fail with an exception', onclick: () => { inject.hidden = !inject.hidden; if (!inject.hidden) exception.focus(); } }, 'Inject exception…'),
      inject),
    el('div', { class: 'ctl-row' },
      button('approval', 'Require approval for this task', 'hold each node of ' + name + ' whose turn to start comes until approved here', () => ({ op: 'approval', task: name }))),
    ...(held ? [el('div', { class: 'ctl-row ctl-held' }, 'held for approval: ',
      button('approve', 'Approve', 'let it start', () => ({ op: 'approve', node: n })),
      button('refuse', 'Refuse', 'it fails with ApprovalRefused', () => ({ op: 'refuse', node: n, reason: reason.value.trim() || 'refused from the viewer' })),
      reason)] : []),
    el('div', { class: 'ctl-row' },
      button('terminate', 'Terminate', 'terminate ' + name + ' {' + n + '} and its subtree', () => ({ op: 'terminate', node: n })),
      button('suspend', 'Suspend', 'nothing new starts in its subtree until resumed', () => ({ op: 'suspend', node: n })),
      button('unsuspend', 'Resume', 'end the suspension of its subtree', () => ({ op: 'unsuspend', node: n }))),
  );
}

// The bar's buttons.
$('ctl-pause').onclick = () => ctl({ op: 'pause' });
$('ctl-continue').onclick = () => ctl({ op: 'resume' });
$('ctl-step').onclick = () => ctl({ op: 'step' });
$('ctl-step-start').onclick = () => ctl({ op: 'step_to_start' });
const taskNamed = () => {
  const t = $('ctl-task').value.trim();
  if (!t) say('name a task first', true);
  return t;
};
$('ctl-break-task').onclick = () => { const t = taskNamed(); if (t) ctl({ op: 'break', at: 'start', task: t }); };
$('ctl-approval-task').onclick = () => { const t = taskNamed(); if (t) ctl({ op: 'approval', task: t }); };

// The run's end (app.js says so in the status line) hides the controls at once.
new MutationObserver(steerDraw).observe($('status'), { childList: true, characterData: true, subtree: true });

// The heartbeat, from a worker where one can run: a page in a background tab keeps its pace.
function everySecond(f) {
  try {
    const src = 'setInterval(() => postMessage(0), 1000);';
    const w = new Worker(URL.createObjectURL(new Blob([src], { type: 'text/javascript' })));
    w.onmessage = f;
    return;
  } catch (e) { /* no worker: the page's own timer */ }
  setInterval(f, 1000);
}
everySecond(() => {
  if (steering()) ctl({ op: 'heartbeat' });
  steerDraw();
});
