// vdrig console: the page's one script (served by vdrig serve, docs/web.md). Reads go out as GET with the token's
// cookie; commands as POST with the token in X-Vdrig-Token (the server refuses a POST without it or from another
// origin). Live state comes from /api/events, the daemon's own subscribe events relayed as Server-Sent Events.
'use strict';

const token = document.querySelector('meta[name="vdrig-token"]').content;
const $ = (id) => document.getElementById(id);
let eventCount = 0;
let current = { state: '?', session: '', views_done: 0, views_total: 0 };
let listTimer = null;

async function getJson(path) {
  const r = await fetch(path, { credentials: 'same-origin' });
  const body = await r.json().catch(() => ({ ok: false, error: r.status + ' ' + r.statusText }));
  return { status: r.status, body };
}

async function post(path, fields) {
  const r = await fetch(path, {
    method: 'POST',
    credentials: 'same-origin',
    headers: { 'Content-Type': 'application/json', 'X-Vdrig-Token': token },
    body: JSON.stringify(fields || {}),
  });
  const body = await r.json().catch(() => ({ ok: false, error: r.status + ' ' + r.statusText }));
  return { status: r.status, body };
}

function errorText(body) {
  return (body.code ? body.code + ': ' : '') + (body.error || 'request failed');
}

function showState() {
  const s = $('state');
  s.textContent = current.state;
  s.className = 'state ' + current.state;
  $('session-name').textContent = current.session || '';
  const total = current.views_total || 0;
  const done = current.views_done || 0;
  $('progress').max = Math.max(total, 1);
  $('progress').value = done;
  $('progress-text').textContent = total ? `views ${done}/${total}` + (current.eta_s !== undefined &&
      current.state === 'running' ? `, ETA ${Math.round(current.eta_s)} s` : '') : '';
  $('frame-text').textContent = current.view !== undefined && current.state === 'running'
    ? `view ${current.view}, bracket frame ${current.bracket_index} (${Number(current.exposure_s).toPrecision(3)} s)`
    : '';
  $('run-error').textContent = current.error ? errorText({ code: current.error_code, error: current.error }) : '';
  $('pause').disabled = current.state !== 'running';
  $('abort').disabled = current.state !== 'running' && current.state !== 'paused';
  $('resume').disabled = current.state === 'running' || !current.session;
}

function cell(row, text) {
  const td = document.createElement('td');
  if (text instanceof Node) td.appendChild(text); else td.textContent = text;
  row.appendChild(td);
  return td;
}

async function refreshSessions() {
  const { body } = await getJson('/api/sessions');
  $('list-error').textContent = body.ok ? '' : errorText(body);
  const rows = $('session-rows');
  rows.replaceChildren();
  for (const s of body.sessions || []) {
    const tr = document.createElement('tr');
    tr.dataset.session = s.session;
    cell(tr, s.session);
    if (s.damaged) {
      const td = cell(tr, 'damaged: ' + s.reason);
      td.colSpan = 6;
      td.className = 'error';
    } else {
      cell(tr, `${s.views_done}/${s.views_total}`);
      const bar = document.createElement('progress');
      bar.max = Math.max(s.views_total, 1);
      bar.value = s.views_done;
      cell(tr, bar);
      cell(tr, s.scheme);
      cell(tr, s.bracket);
      const link = document.createElement('a');
      link.href = '/files/' + encodeURIComponent(s.session) + '/manifest.json';
      link.textContent = 'manifest';
      cell(tr, link);
      const resume = document.createElement('button');
      resume.textContent = 'Resume';
      resume.type = 'button';
      resume.disabled = s.views_done >= s.views_total || current.state === 'running';
      resume.addEventListener('click', () => command('resume', { session: s.session }));
      cell(tr, resume);
    }
    rows.appendChild(tr);
  }
}

// The list is read again when a view completes or the state changes, at most twice a second.
function scheduleList() {
  if (listTimer) return;
  listTimer = setTimeout(() => { listTimer = null; refreshSessions(); }, 500);
}

async function command(verb, fields) {
  const { body } = await post('/api/' + verb, fields);
  $('run-error').textContent = body.ok ? '' : errorText(body);
  if (body.ok) scheduleList();
  return body;
}

function onEvent(ev) {
  eventCount += 1;
  $('event-count').textContent = String(eventCount);
  if (ev.event === 'daemon') {
    $('daemon').textContent = ev.connected ? 'vdrigd connected' : 'vdrigd not reachable';
    $('daemon').className = 'badge ' + (ev.connected ? 'up' : 'down');
    return;
  }
  if (ev.event === 'status') {
    current = Object.assign({}, ev);
  } else if (ev.event === 'state') {
    current.state = ev.state;
    current.session = ev.session;
    current.error = ev.error;
    current.error_code = ev.error_code;
    scheduleList();
  } else if (ev.event === 'progress') {
    Object.assign(current, ev);
    if (ev.view_finished) scheduleList();
  }
  showState();
}

function listen() {
  const source = new EventSource('/api/events');
  source.onmessage = (m) => {
    try {
      onEvent(JSON.parse(m.data));
    } catch (e) {
      console.warn('unreadable event', m.data);
    }
  };
  source.onerror = () => {
    $('daemon').textContent = 'console reconnecting…';
    $('daemon').className = 'badge down';
  };
}

$('start-form').addEventListener('submit', async (e) => {
  e.preventDefault();
  const form = new FormData(e.target);
  const fields = {};
  for (const [k, v] of form.entries()) fields[k] = String(v).trim();
  const { body } = await post('/api/start', fields);
  $('start-error').textContent = body.ok ? '' : errorText(body);
  if (body.ok) scheduleList();
});
for (const verb of ['pause', 'resume', 'abort', 'stop'])
  $(verb).addEventListener('click', () => command(verb, verb === 'resume' && current.session
                                                   ? { session: current.session } : {}));
$('refresh').addEventListener('click', refreshSessions);

showState();
refreshSessions();
listen();
