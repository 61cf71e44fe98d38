// vdrig console: the page's one script (served by vdrig serve, docs/web.md). Reads go out as GET with the token's
// cookie; commands as POST with the token in X-Vdrig-Token (the server refuses a POST without it or from another
// origin). Live state comes from /api/events, the daemon's own subscribe events relayed as Server-Sent Events.
'use strict';

const token = document.querySelector('meta[name="vdrig-token"]').content;
const $ = (id) => document.getElementById(id);
let eventCount = 0;
let current = { state: '?', session: '', views_done: 0, views_total: 0 };
let listTimer = null;
// The session whose manifest is drawn, its views, the ones captured, the stage's last known position.
let plan = { session: '', views: [], done: new Set(), current: -1 };
let position = null;
const exposures = new Map();  // 'view/bracket' -> exposure_s, from the progress events
let frameBusy = false, frameWanted = null, logTimer = null, logDirty = false, measured = null;

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

// The planned views seen from above: radius = zenith angle (0 at the centre, 90° at the rim), angle = azimuth.
function drawHemisphere() {
  const canvas = $('hemisphere');
  const g = canvas.getContext('2d');
  const r0 = canvas.width / 2 - 8, cx = canvas.width / 2, cy = canvas.height / 2;
  g.clearRect(0, 0, canvas.width, canvas.height);
  g.strokeStyle = '#c5c9d0';
  for (const z of [30, 60, 90]) {
    g.beginPath();
    g.arc(cx, cy, r0 * z / 90, 0, 2 * Math.PI);
    g.stroke();
  }
  for (const v of plan.views) {
    const rad = r0 * Math.min(v.zenith_deg, 90) / 90, a = v.azimuth_deg * Math.PI / 180;
    const x = cx + rad * Math.cos(a), y = cy - rad * Math.sin(a);
    g.beginPath();
    g.arc(x, y, 3, 0, 2 * Math.PI);
    g.fillStyle = plan.done.has(v.index) ? '#2e7d32' : '#ffffff';
    g.fill();
    g.strokeStyle = plan.done.has(v.index) ? '#2e7d32' : '#8a909a';
    g.stroke();
    if (v.index === plan.current) {
      g.beginPath();
      g.arc(x, y, 7, 0, 2 * Math.PI);
      g.strokeStyle = '#e65100';
      g.lineWidth = 2;
      g.stroke();
      g.lineWidth = 1;
    }
  }
  canvas.dataset.done = String(plan.done.size);
  canvas.dataset.views = String(plan.views.length);
  $('hemisphere-text').textContent = plan.session
    ? `${plan.session}: ${plan.done.size} of ${plan.views.length} views captured` : 'no session';
}

// A new session in hand: its manifest (the planned views) and its journal (the views already captured).
async function loadPlan(session) {
  plan = { session, views: [], done: new Set(), current: -1 };
  drawHemisphere();
  const m = await fetch('/files/' + encodeURIComponent(session) + '/manifest.json', { credentials: 'same-origin' });
  if (!m.ok || plan.session !== session) return;
  const manifest = await m.json();
  plan.views = manifest.views || [];
  const j = await fetch('/files/' + encodeURIComponent(session) + '/journal.jsonl', { credentials: 'same-origin' });
  if (j.ok && plan.session === session) {
    for (const line of (await j.text()).split('\n')) {
      let rec = null;
      try { rec = JSON.parse(line); } catch (e) { continue; }  // a line being written
      if (rec.type === 'view_complete') plan.done.add(rec.view);
      if (rec.type === 'view_redo') plan.done.delete(rec.view);
    }
  }
  drawHemisphere();
  showDrive();
}

function showDrive() {
  const v = plan.views.find((w) => w.index === current.view);
  const target = v && v.target ? `, target pan ${v.target.pan_deg.toFixed(1)}°, tilt ${v.target.tilt_deg.toFixed(1)}°` : '';
  const stage = current.stage === 'moving' ? 'moving (home/move)' : current.state === 'running' ? 'capturing' : 'idle';
  const at = measured ? `, measured pan ${measured.pan_deg.toFixed(2)}°, tilt ${measured.tilt_deg.toFixed(2)}°` : '';
  $('drive-text').textContent = `drive: ${stage}` +
    (current.view !== undefined && current.session ? `, view ${current.view}` + target + at : '');
  $('camera-text').textContent = current.exposure_s !== undefined && current.session
    ? `camera: exposure ${Number(current.exposure_s).toPrecision(3)} s, bracket frame ${current.bracket_index}` : 'camera: –';
}

// The last frame as a tone-mapped thumbnail: one request at a time, the newest frame wanted meanwhile next.
async function loadFrame(session, view, bracket) {
  if (frameBusy) {
    frameWanted = [session, view, bracket];
    return;
  }
  frameBusy = true;
  try {
    const q = `session=${encodeURIComponent(session)}&view=${view}&bracket=${bracket}`;
    const { status, body } = await getJson('/api/frame?' + q);
    if (status === 429) {
      // Rate-limited: the newest frame is asked for again in a second, unless a newer one is wanted by then.
      setTimeout(() => { if (!frameWanted && !frameBusy) loadFrame(session, view, bracket); }, 1000);
    } else if (status === 200 && body.ok) {
      const img = $('thumbnail');
      img.src = 'data:image/png;base64,' + body.png_base64;
      img.width = body.thumb_width;
      img.height = body.thumb_height;
      img.dataset.view = String(body.view);
      img.dataset.bracket = String(body.bracket_index);
      img.dataset.saturated = String(body.saturated_fraction);
      const sat = (100 * body.saturated_fraction).toFixed(body.saturated_fraction < 0.01 ? 2 : 1);
      $('thumbnail-text').textContent = `view ${body.view}, bracket frame ${body.bracket_index}` +
        (exposures.has(`${body.view}/${body.bracket_index}`)
          ? ` (${Number(exposures.get(`${body.view}/${body.bracket_index}`)).toPrecision(3)} s)` : '') +
        `, ${body.width}×${body.height} ${body.bits}-bit, saturated ${sat}%`;
    }
  } finally {
    frameBusy = false;
    if (frameWanted) {
      const next = frameWanted;
      frameWanted = null;
      loadFrame(...next);
    }
  }
}

function describeJournalLine(line) {
  const r = JSON.parse(line);
  const when = r.utc ? r.utc.replace(/^.*T/, '').replace(/Z$/, '') + ' ' : '';
  if (r.type === 'frame') return `${when}view ${r.view} frame ${r.bracket}: ${Number(r.exposure_s).toPrecision(3)} s` +
    (r.saturated ? ' saturated' : '');
  if (r.type === 'view_complete') return `${when}view ${r.view} complete`;
  if (r.type === 'event') return `${when}${r.event}: ${r.message || r.code || ''}`;
  return when + (r.type || '?') + (r.view !== undefined ? ' view ' + r.view : '');
}

// The journal's last lines, read again at most once a second while events come (and once more after the last).
// Its last frame line says where the stage measured itself: the drive's state as the capture saw it.
function scheduleLog() {
  if (!current.session) return;
  if (logTimer) {
    logDirty = true;
    return;
  }
  logTimer = setTimeout(async () => {
    logDirty = false;
    try {
      const r = await fetch('/files/' + encodeURIComponent(current.session) + '/journal.jsonl?tail=12',
                            { credentials: 'same-origin' });
      if (r.ok) {
        const lines = (await r.text()).split('\n').filter((l) => l);
        const shown = [];
        for (const l of lines) {
          try {
            const rec = JSON.parse(l);
            if (rec.type === 'frame' && rec.measured) measured = rec.measured;
            shown.push(describeJournalLine(l));
          } catch (e) {
            shown.push(l);
          }
        }
        $('log-tail').textContent = shown.join('\n');
        showDrive();
      }
    } finally {
      logTimer = null;
      if (logDirty) scheduleLog();
    }
  }, 1000);
}

function showPosition() {
  $('stage-text').textContent = position
    ? `pan ${position.pan_deg.toFixed(2)}°, tilt ${position.tilt_deg.toFixed(2)}°` : 'position unknown: home first';
  for (const b of document.querySelectorAll('[data-jog]')) b.disabled = !position || current.state === 'running';
  $('home').disabled = current.state === 'running';
}

async function stageCommand(verb, fields) {
  $('stage-error').textContent = '';
  $('stage-text').textContent = verb === 'home' ? 'homing…' : 'moving…';
  const { body } = await post('/api/' + verb, fields);
  if (body.ok) position = { pan_deg: body.pan_deg, tilt_deg: body.tilt_deg };
  else $('stage-error').textContent = errorText(body);
  showPosition();
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
      const files = cell(tr, link);
      // A complete session's results: the report `vdrig report S --out S/report.html` wrote (when it is there: the
      // server says so in `report`), and its maps in WebGL2.
      if (s.views_done >= s.views_total) {
        const results = [['viewer', '/viewer?session=' + encodeURIComponent(s.session)]];
        if (s.report) results.unshift(['report', '/report/' + encodeURIComponent(s.session)]);
        for (const [text, href] of results) {
          const a = document.createElement('a');
          a.href = href;
          a.textContent = text;
          a.target = '_blank';
          a.rel = 'noopener';
          files.append(' ', a);
        }
      }
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
  const before = current.session;
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
    if (ev.view_finished) plan.done.add(ev.view);
    plan.current = ev.view;
    if (!ev.view_finished) {
      exposures.set(`${ev.view}/${ev.bracket_index}`, ev.exposure_s);
      if (exposures.size > 256) exposures.delete(exposures.keys().next().value);
      loadFrame(ev.session, ev.view, ev.bracket_index);
    }
    drawHemisphere();
  }
  if (current.session && (current.session !== before || plan.session !== current.session)) loadPlan(current.session);
  if (ev.event === 'state' && ev.state !== 'running') {
    plan.current = -1;
    drawHemisphere();
    // The session stopped: its last frame is the thumbnail, whatever frames were skipped on the way.
    if (current.view !== undefined && current.bracket_index !== undefined)
      loadFrame(current.session, current.view, current.bracket_index);
  }
  scheduleLog();
  showState();
  showDrive();
  showPosition();
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
$('home').addEventListener('click', () => stageCommand('home', {}));
for (const b of document.querySelectorAll('[data-jog]')) {
  b.addEventListener('click', () => {
    const [axis, sign] = b.dataset.jog.split(',');
    const step = Number($('jog-step').value) * Number(sign);
    if (!position || !Number.isFinite(step)) return;
    const target = { pan_deg: position.pan_deg, tilt_deg: position.tilt_deg };
    target[axis + '_deg'] += step;
    stageCommand('move', target);
  });
}

showState();
drawHemisphere();
showPosition();
refreshSessions();
listen();
