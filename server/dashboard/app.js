// foamd's dashboard: the job list, one job, one sweep. Plain ES2020 over foamd's read-only
// JSON routes, charts by Chart.js 3 (served by foamd as chart.js), a job's cells in 3D by
// view3d.js (three.js). Routes live in the fragment:
// #/ (jobs, with ?state=&tag=&sweep= filters), #/job/ID, #/sweep/ID; #token=T hands over a token.
'use strict';

const POLL_MS = 3000;
const JOBS_PAGE_SIZE = 100;
const TOKEN_KEY = 'foamd.token';
// Sample columns that describe the solver rather than the tissue.
const BOOKKEEPING = new Set(['t_s', 'steps', 'wall_s', 'cg_iters_mean', 'volume_error_max',
  'dt_min_s', 'steps_rejected']);
// What each scene is about: its main sample column, and the result a sweep compares.
const MAIN_COLUMN = {fusion: 'theta_deg', doublet: 'contact_angle_deg', cell: 'aspect_ratio',
  spheroid: 'radius_gyration_um'};
const MAIN_RESULT = {fusion: 'theta_eq_deg', doublet: 'contact_angle_deg', cell: 'aspect_ratio',
  spheroid: 'radius_gyration_um'};
const COLORS = ['#1c6bb0', '#d9480f', '#2b8a3e', '#7048e8', '#c2255c', '#0b7285', '#e67700', '#5c5f66'];

// ---- small DOM helpers: server data only ever enters the page as text ----------------------

const $ = sel => document.querySelector(sel);

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === undefined || v === null || v === false) continue;
    if (k === 'class') node.className = v;
    else node.setAttribute(k, v === true ? '' : String(v));
  }
  for (const c of children) {
    if (c === undefined || c === null) continue;
    node.append(c instanceof Node ? c : String(c));
  }
  return node;
}

const fromTemplate = id => document.getElementById(id).content.cloneNode(true);
const isNum = v => typeof v === 'number' && Number.isFinite(v);
const enc = encodeURIComponent;

function dec(text) {
  try {
    return decodeURIComponent(text);
  } catch {
    return text;  // a stray '%' typed into the address
  }
}

function formatNumber(v) {
  if (!isNum(v)) return v === null || v === undefined ? '–' : String(v);
  if (Number.isInteger(v) && Math.abs(v) < 1e15) return String(v);
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e6)) return v.toExponential(3);
  return String(Number(v.toPrecision(6)));
}

function formatDuration(s) {
  if (!isNum(s) || s < 0) return '';
  if (s < 1) return '<1 s';
  if (s < 60) return `${Math.round(s)} s`;
  if (s < 3600) {
    const m = Math.floor(s / 60), r = Math.round(s - 60 * m);
    return m < 10 && r ? `${m} min ${r} s` : `${Math.round(s / 60)} min`;
  }
  const h = Math.floor(s / 3600);
  return `${h} h ${Math.round((s - 3600 * h) / 60)} min`;
}

function formatTime(iso) {
  const t = Date.parse(iso);
  if (!iso || Number.isNaN(t)) return '';
  const d = new Date(t), pad = n => String(n).padStart(2, '0');
  const hm = `${pad(d.getHours())}:${pad(d.getMinutes())}:${pad(d.getSeconds())}`;
  return d.toDateString() === new Date().toDateString()
    ? hm : `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())} ${hm}`;
}

// "JOB_STATE_SUCCEEDED" -> "succeeded"
const stateName = s => String(s || '').replace(/^JOB_STATE_/, '').toLowerCase() || 'unknown';
const stateBadge = (state, id) => el('span', {class: `state state-${state}`, id}, state);

function parseSpec(job) {
  try {
    return JSON.parse(job.spec_json || '{}') || {};
  } catch {
    return {};
  }
}

// A value of a spec by its full path, "cells.alpha" or "seed".
const specValue = (spec, path) => path.split('.').reduce((o, k) => (o == null ? undefined : o[k]), spec);

// ---- token and requests ---------------------------------------------------------------------

let token = '';
try {
  token = sessionStorage.getItem(TOKEN_KEY) || '';
} catch { /* storage disabled: the token lives as long as the page */ }

function storeToken(t) {
  token = t;
  try {
    if (t) sessionStorage.setItem(TOKEN_KEY, t);
    else sessionStorage.removeItem(TOKEN_KEY);
  } catch { /* see above */ }
  $('#forget-token').hidden = !t;
}

// A fragment never reaches the server, which makes it the place to hand a token to the page;
// it is taken out of the address bar (and the history) at once.
function takeTokenFromFragment() {
  const m = /^#token=([^&]*)/.exec(location.hash);
  if (!m) return;
  storeToken(dec(m[1]).trim());
  history.replaceState(null, '', `${location.pathname}${location.search}#/`);
}

class AuthError extends Error {}

// An answer of foamd other than 401; status 0 when it did not answer at all.
class HttpError extends Error {
  constructor(message, status) {
    super(message);
    this.status = status;
  }
}

async function errorText(res) {
  const text = await res.text().catch(() => '');
  try {
    const j = JSON.parse(text);
    if (j && typeof j.error === 'string') return j.error;
  } catch { /* not JSON */ }
  return `HTTP ${res.status}${text ? `: ${text.slice(0, 200)}` : ''}`;
}

async function request(path) {
  const headers = token ? {Authorization: `Bearer ${token}`} : {};
  let res;
  try {
    res = await fetch(path, {headers, cache: 'no-store'});
  } catch (e) {
    throw new HttpError(`foamd did not answer (${path}): ${e.message}`, 0);
  }
  if (res.status === 401) throw new AuthError(await errorText(res));
  if (!res.ok) throw new HttpError(`${path.split('?')[0]}: ${await errorText(res)}`, res.status);
  return res;
}

const getJson = async path => (await request(path)).json();

// Every job of a query, page by page.
async function allJobs(query) {
  const jobs = [];
  let pageToken = '';
  for (let i = 0; i < 100; i++) {
    const page = await getJson(`jobs?${query}&page_size=1000${pageToken ? `&page_token=${enc(pageToken)}` : ''}`);
    jobs.push(...(page.jobs || []));
    pageToken = page.next_page_token || '';
    if (!pageToken) break;
  }
  return jobs;
}

function showError(message) {
  const box = $('#error');
  box.textContent = message;
  box.hidden = false;
}

function hideError() {
  $('#error').hidden = true;
}

async function refreshHealth() {
  const badge = $('#health');
  try {
    const res = await fetch('healthz', {cache: 'no-store'});
    const body = await res.json().catch(() => ({}));
    const ok = res.ok && body.status === 'ok';
    badge.textContent = ok ? 'healthy' : (body.status || `HTTP ${res.status}`);
    badge.title = ok ? 'foamd /healthz' : (body.store_error || JSON.stringify(body));
    badge.className = `health ${ok ? 'ok' : 'bad'}`;
  } catch {
    badge.textContent = 'unreachable';
    badge.className = 'health bad';
  }
  badge.hidden = false;
}

// ---- views and polling ----------------------------------------------------------------------

let generation = 0;  // bumped whenever a view (re)starts: answers meant for an older one are dropped
let pollTimer = 0;
let charts = [];     // the current view's Chart.js instances and 3D view, destroyed when it is left

function stopPolling() {
  generation++;
  clearTimeout(pollTimer);
}

// Runs refresh now and again every POLL_MS for as long as it returns true and the view is current.
function poll(refresh) {
  stopPolling();
  const gen = generation;
  const live = () => gen === generation;
  const tick = async () => {
    let again = true;
    refreshHealth();
    try {
      again = await refresh(live);
      if (live()) hideError();
    } catch (e) {
      if (!live()) return;
      if (e instanceof AuthError) {
        askForToken(e.message);
        return;
      }
      showError(e.message);
      // Asking again cannot mend a bad request or an unknown job; anything else may be a
      // foamd that is restarting.
      again = !(e instanceof HttpError && e.status >= 400 && e.status < 500);
    }
    if (live() && again) pollTimer = setTimeout(tick, POLL_MS);
  };
  tick();
}

function askForToken(serverMessage) {
  stopPolling();
  const rejected = Boolean(token);
  storeToken('');
  $('#view').replaceChildren();
  hideError();
  const message = $('#token-message');
  message.textContent = rejected ? `foamd did not accept the token (${serverMessage}).` : '';
  message.hidden = !rejected;
  $('#token-prompt').hidden = false;
  $('#token-input').value = '';
  $('#token-input').focus();
}

function parseRoute() {
  const [path, query = ''] = location.hash.replace(/^#/, '').split('?');
  const m = /^\/(job|sweep)\/(.+)$/.exec(path);
  if (m) return {name: m[1], id: dec(m[2])};
  return {name: 'jobs', params: new URLSearchParams(query)};
}

function route() {
  takeTokenFromFragment();
  stopPolling();
  charts.forEach(c => c.destroy());
  charts = [];
  hideError();
  $('#token-prompt').hidden = true;
  const view = $('#view');
  view.replaceChildren();
  const r = parseRoute();
  $('#nav-jobs').classList.toggle('active', r.name === 'jobs');
  if (r.name === 'job') showJob(view, r.id);
  else if (r.name === 'sweep') showSweep(view, r.id);
  else showJobs(view, r.params);
  window.scrollTo(0, 0);
}

// ---- charts ---------------------------------------------------------------------------------

function lineChart(canvas, yAxes) {
  if (typeof Chart === 'undefined') return chartStub(canvas);
  const scales = {x: {type: 'linear', title: {display: true, text: 't'}, grid: {color: '#eef0f3'}}};
  yAxes.forEach(({id, title, position}) => {
    scales[id] = {type: 'linear', position, title: {display: true, text: title},
      grid: {color: '#eef0f3', drawOnChartArea: position !== 'right'}};
  });
  const chart = new Chart(canvas, {
    type: 'line',
    data: {datasets: []},
    options: {
      animation: false,
      responsive: true,
      maintainAspectRatio: false,
      interaction: {mode: 'nearest', intersect: false},
      plugins: {legend: {labels: {boxWidth: 12, filter: (item, data) => !data.datasets[item.datasetIndex].band}}},
      scales,
    },
  });
  charts.push(chart);
  return chart;
}

// Without Chart.js (chart.js failed to load) the views still work, minus their charts.
function chartStub(canvas) {
  showError('chart.js did not load: no charts');
  const axis = () => ({title: {}});
  return {canvas, data: {datasets: []}, update() {}, destroy() {},
    options: {plugins: {legend: {}}, scales: {x: axis(), y: axis(), y1: axis()}}};
}

function dataset(label, points, color, extra = {}) {
  return {label, data: points, borderColor: color, backgroundColor: color, borderWidth: 2,
    pointRadius: 2.5, pointHoverRadius: 4, tension: 0, ...extra};
}

// The (t, y) pairs of one sample column; rows where either is null (NaN on the server) are left out.
function columnPoints(samples, column) {
  const ti = samples.columns.indexOf('t_s'), yi = samples.columns.indexOf(column);
  const points = [];
  if (ti < 0 || yi < 0) return points;
  for (const row of samples.rows) {
    if (isNum(row[ti]) && isNum(row[yi])) points.push([row[ti], row[yi]]);
  }
  return points;
}

// Minutes once a run is long enough for seconds to become unreadable.
const timeUnit = tMax => (tMax > 1200 ? {scale: 60, label: 't (min)'} : {scale: 1, label: 't (s)'});

// θ(t) of the fits foam-run makes to a fusion, over [0, tMax] seconds (docs/model.md §8.2–§8.4).
function fitCurves(results, tMax) {
  const r = Object.fromEntries(results.map(x => [x.name, x.value]));
  const has = (...names) => names.every(n => isNum(r[n]));
  const grid = Array.from({length: 121}, (_, i) => (tMax * i) / 120);
  const curves = [];
  if (r.eq1_ok === 1 && has('theta_eq_deg', 'theta0_deg', 'tau_f_s')) {
    const f = t => r.theta_eq_deg + (r.theta0_deg - r.theta_eq_deg) * Math.exp(-t / r.tau_f_s);
    curves.push({label: `Eq. 1: θeq = ${r.theta_eq_deg.toFixed(1)}°, τf = ${r.tau_f_s.toFixed(0)} s`,
      points: grid.map(t => [t, f(t)]), dash: []});
  }
  if (r.eq2_ok === 1 && has('tau_gamma_s', 'tau_eps_s', 'eq2_theta0_deg')) {
    // Closed form of Eq. 2 in u = cos θ.
    const k = r.tau_eps_s / r.tau_gamma_s, root = Math.sqrt(k * k + 4);
    const up = (root - k) / 2, um = (-root - k) / 2, lambda = root / (2 * r.tau_eps_s);
    const u0 = Math.cos((r.eq2_theta0_deg * Math.PI) / 180), c = (u0 - up) / (u0 - um);
    const f = t => {
      const e = c * Math.exp(-lambda * t);
      const u = Math.min(1, Math.max(-1, (up - um * e) / (1 - e)));
      return (Math.acos(u) * 180) / Math.PI;
    };
    curves.push({label: `Eq. 2: τΓ = ${r.tau_gamma_s.toFixed(0)} s, τε = ${r.tau_eps_s.toFixed(0)} s`,
      points: grid.map(t => [t, f(t)]), dash: [6, 4]});
  }
  return curves;
}

// ---- #/ : the job list ----------------------------------------------------------------------

function showJobs(view, params) {
  document.title = 'Jobs · foamd';
  view.append(fromTemplate('tpl-jobs'));
  const filters = {state: params.get('state') || '', tag: params.get('tag') || '', sweep: params.get('sweep') || ''};
  const pages = [''];  // page tokens of the pages seen so far: back is a pop
  const inputs = {state: $('#filter-state'), tag: $('#filter-tag'), sweep: $('#filter-sweep')};

  const restart = () => poll(live => refreshJobs(live, filters, pages));
  let debounce = 0;
  for (const [key, input] of Object.entries(inputs)) {
    if (key === 'state' && filters.state && ![...input.options].some(o => o.value === filters.state)) {
      input.append(el('option', {value: filters.state}, filters.state));
    }
    input.value = filters[key];
    input.addEventListener('input', () => {
      filters[key] = input.value.trim();
      // Filters go into the address (without a hashchange) so that a view can be bookmarked.
      const q = new URLSearchParams(Object.entries(filters).filter(([, v]) => v)).toString().replace(/%2C/g, ',');
      history.replaceState(null, '', `#/${q ? `?${q}` : ''}`);
      pages.length = 1;
      clearTimeout(debounce);
      debounce = setTimeout(restart, key === 'state' ? 0 : 250);
    });
  }
  $('#job-filters').addEventListener('submit', e => e.preventDefault());
  $('#jobs-older').addEventListener('click', () => {
    pages.push($('#jobs-older').dataset.token);
    restart();
  });
  $('#jobs-newer').addEventListener('click', () => {
    if (pages.length > 1) pages.pop();
    restart();
  });
  restart();
}

async function refreshJobs(live, filters, pages) {
  const q = new URLSearchParams({page_size: JOBS_PAGE_SIZE});
  for (const [k, v] of Object.entries(filters)) if (v) q.set(k, v);
  if (pages.length > 1) q.set('page_token', pages[pages.length - 1]);
  const list = await getJson(`jobs?${q}`);
  if (!live()) return false;
  const jobs = list.jobs || [];
  const body = $('#jobs tbody');
  body.replaceChildren(...jobs.map(jobRow));
  if (!jobs.length) {
    const what = Object.values(filters).some(Boolean) ? 'No job matches these filters.' : 'No jobs yet.';
    body.append(el('tr', {class: 'empty'}, el('td', {colspan: 9}, what)));
  }
  const older = $('#jobs-older');
  older.hidden = !list.next_page_token;
  older.dataset.token = list.next_page_token || '';
  $('#jobs-newer').hidden = pages.length < 2;
  const first = (pages.length - 1) * JOBS_PAGE_SIZE;
  $('#jobs-count').textContent = jobs.length
    ? `jobs ${first + 1}–${first + jobs.length}${list.next_page_token ? '' : ` of ${first + jobs.length}`}` : '';
  return true;
}

function progressCell(job, state) {
  const p = isNum(job.progress) ? Math.min(1, Math.max(0, job.progress)) : 0;
  const bar = el('progress', {max: 1, value: p});
  let text = `${Math.round(100 * p)}%`;
  if (state === 'running') {
    const started = Date.parse(job.started_utc);
    // A constant rate since the start: crude, but the engine's step size settles early.
    if (p > 0.005 && !Number.isNaN(started)) {
      const elapsed = (Date.now() - started) / 1000;
      text += ` · ETA ${formatDuration((elapsed * (1 - p)) / p)}`;
    }
  } else if (state === 'queued') {
    text = 'waiting';
  } else if (state === 'succeeded') {
    const took = (Date.parse(job.finished_utc) - Date.parse(job.started_utc)) / 1000;
    text = isNum(took) ? `took ${formatDuration(took)}` : 'done';
  }
  return [bar, el('span', {class: 'muted'}, text)];
}

function jobRow(job) {
  const state = stateName(job.state);
  const preset = specValue(parseSpec(job), 'numerics.preset');
  return el('tr', {'data-job-id': job.id, class: `row-${state}`},
    el('td', {}, el('a', {href: `#/job/${enc(job.id)}`, class: 'mono'}, job.id)),
    el('td', {}, job.scene),
    el('td', {}, stateBadge(state)),
    el('td', {class: 'outcome'}, job.outcome || ''),
    el('td', {class: 'progress-col'}, ...progressCell(job, state)),
    el('td', {}, typeof preset === 'string' ? preset : ''),
    el('td', {}, job.tag || ''),
    el('td', {}, job.sweep_id ? el('a', {href: `#/sweep/${enc(job.sweep_id)}`, class: 'mono'}, job.sweep_id) : ''),
    el('td', {class: 'muted', title: job.created_utc}, formatTime(job.created_utc)));
}

// ---- #/job/ID -------------------------------------------------------------------------------

// A plain link would not carry the Authorization header: fetch, then save through a Blob URL.
async function downloadWithToken(event) {
  event.preventDefault();
  const link = event.currentTarget;
  if (link.getAttribute('aria-disabled') === 'true') return;
  try {
    const blob = await (await request(link.getAttribute('href'))).blob();
    const url = URL.createObjectURL(blob);
    const a = el('a', {href: url, download: link.getAttribute('download')});
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 60000);
  } catch (e) {
    if (e instanceof AuthError) askForToken(e.message);
    else showError(e.message);
  }
}

function showJob(view, id) {
  document.title = `${id} · foamd`;
  view.append(fromTemplate('tpl-job'));
  $('#job-id').textContent = id;
  const links = [['#samples-csv', 'samples.csv', `${id}-samples.csv`],
    ['#vtk-export', 'snapshots/latest.vtp', `${id}-latest.vtp`]];
  for (const [sel, route, file] of links) {
    const a = $(sel);
    a.href = `jobs/${enc(id)}/${route}`;
    a.download = file;
    a.addEventListener('click', downloadWithToken);
  }
  const ctx = {
    id,
    column: null,  // the sample column chosen in #main-column; null = the scene's main one
    main: lineChart($('#main-chart'), [{id: 'y', position: 'left', title: ''}]),
    health: lineChart($('#health-chart'), [
      {id: 'y', position: 'left', title: 'CG iterations / rejected steps'},
      {id: 'y1', position: 'right', title: 'volume error'}]),
    data: null,
    view: new View3D.View($('#view3d'), id, async path => (await request(path)).arrayBuffer(), e => {
      if (e instanceof AuthError) askForToken(e.message);
      else showError(e.message);
    }),
  };
  charts.push(ctx.view);
  // For tests and scripts: the 3D view (its three.js scene, camera and renderer).
  window.foamdView3D = ctx.view;
  $('#main-column').addEventListener('change', e => {
    ctx.column = e.target.value;
    if (ctx.data) drawJobCharts(ctx);
  });
  poll(live => refreshJob(live, ctx));
}

async function refreshJob(live, ctx) {
  const base = `jobs/${enc(ctx.id)}`;
  const [res, samples] = await Promise.all([getJson(`${base}/results`), getJson(`${base}/samples`)]);
  if (!live()) return false;
  const job = res.job || {};
  const state = stateName(job.state);
  samples.columns = samples.columns || [];
  samples.rows = samples.rows || [];
  ctx.data = {job, results: res.results || [], samples};

  $('#job-state').replaceWith(stateBadge(state, 'job-state'));
  const spec = parseSpec(job);
  const facts = [
    ['scene', job.scene], ['outcome', job.outcome], ['seed', job.seed], ['preset', specValue(spec, 'numerics.preset')],
    ['tag', job.tag], ['sweep', job.sweep_id && el('a', {href: `#/sweep/${enc(job.sweep_id)}`, class: 'mono'}, job.sweep_id)],
    ['progress', state === 'running' ? progressCell(job, state) : null],
    ['simulated', isNum(job.t_s) ? `${formatNumber(job.t_s)} s` : null],
    ['created', formatTime(job.created_utc)], ['started', formatTime(job.started_utc)],
    ['finished', formatTime(job.finished_utc)], ['attempts', job.attempts > 1 ? job.attempts : null],
    ['failure', job.failure_kind], ['engine', job.engine_version]];
  $('#job-facts').replaceChildren(...facts.filter(([, v]) => v !== null && v !== undefined && v !== '')
    .map(([k, v]) => el('div', {}, el('dt', {}, k), el('dd', {}, ...(Array.isArray(v) ? v : [v])))));
  $('#job-reason').textContent = job.reason || '';
  $('#job-reason').hidden = !job.reason;

  const snaps = res.snapshots || [];
  const vtk = $('#vtk-export');
  vtk.setAttribute('aria-disabled', String(!snaps.length));
  vtk.title = snaps.length ? '' : 'the job has no snapshot yet';
  ctx.view.setSnapshots(snaps);
  const last = snaps[snaps.length - 1];
  $('#job-snapshots').textContent = last
    ? `${snaps.length} snapshot${snaps.length > 1 ? 's' : ''}, latest at t = ${formatNumber(last.t_s)} s` : '';

  const specText = JSON.stringify(spec, null, 2);
  if ($('#job-spec').textContent !== specText) $('#job-spec').textContent = specText;

  $('#results tbody').replaceChildren(...ctx.data.results.map(r =>
    el('tr', {'data-name': r.name}, el('td', {}, r.name),
      el('td', {class: 'num', title: String(r.value)}, formatNumber(r.value)))));
  $('#results-empty').hidden = ctx.data.results.length > 0;

  drawJobCharts(ctx);
  return !job.terminal;  // the server says when a job has ended
}

function drawJobCharts(ctx) {
  const {job, results, samples} = ctx.data;
  const columns = samples.columns;
  const choices = columns.filter(c => c !== 't_s');
  const preferred = MAIN_COLUMN[job.scene];
  const fallback = columns.includes(preferred) ? preferred
    : columns.find(c => !BOOKKEEPING.has(c)) || choices[0] || '';
  const column = choices.includes(ctx.column) ? ctx.column : fallback;

  const select = $('#main-column');
  if (select.options.length !== choices.length || select.value !== column) {
    select.replaceChildren(...choices.map(c => el('option', {value: c}, c)));
    select.value = column;
  }
  select.hidden = !choices.length;
  $('#main-caption').textContent = choices.length ? 'over time' : 'No samples yet.';

  const points = columnPoints(samples, column);
  const tMax = points.reduce((m, p) => Math.max(m, p[0]), 0);
  const unit = timeUnit(Math.max(tMax, isNum(job.t_s) ? job.t_s : 0));
  const scaled = pts => pts.map(([t, y]) => ({x: t / unit.scale, y}));

  const main = ctx.main;
  main.data.datasets = [dataset(column, scaled(points), COLORS[0])];
  if (column === 'theta_deg' && tMax > 0) {
    fitCurves(results, tMax).forEach((c, i) => main.data.datasets.push(
      dataset(c.label, scaled(c.points), COLORS[1 + i], {pointRadius: 0, borderDash: c.dash})));
  }
  main.options.plugins.legend.display = points.length > 0;
  main.options.scales.x.title.text = unit.label;
  main.options.scales.y.title.text = column;
  main.update();
  // For tests and scripts: the plotted samples exactly as foamd sent them, t in seconds.
  main.canvas.dataset.points = JSON.stringify(points);
  main.canvas.dataset.column = column;

  const health = ctx.health;
  const series = [['cg_iters_mean', 'y'], ['steps_rejected', 'y'], ['volume_error_max', 'y1']]
    .filter(([c]) => columns.includes(c));
  health.data.datasets = series.map(([c, axis], i) =>
    dataset(c, scaled(columnPoints(samples, c)), COLORS[i], {yAxisID: axis, pointRadius: 1.5, borderWidth: 1.5}));
  health.options.scales.x.title.text = unit.label;
  health.options.plugins.legend.display = series.length > 0;
  health.options.scales.y1.display = series.some(([, axis]) => axis === 'y1');
  health.update();
}

// ---- #/sweep/ID -----------------------------------------------------------------------------

function quantile(sorted, q) {
  if (!sorted.length) return NaN;
  const pos = (sorted.length - 1) * q, lo = Math.floor(pos), hi = Math.ceil(pos);
  return sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo);
}

const compareValues = (a, b) => (isNum(a) && isNum(b) ? a - b : String(a).localeCompare(String(b)));
const formatValue = v => (isNum(v) ? String(v) : v === undefined ? '–' : typeof v === 'string' ? v : JSON.stringify(v));

// Spec paths whose values differ between the jobs: the swept keys of a sweep that predates
// foamd recording them (derived values such as scene.gap_um may show up too).
function differingKeys(specs) {
  const flat = (o, prefix = '', out = {}) => {
    for (const [k, v] of Object.entries(o || {})) {
      if (v && typeof v === 'object' && !Array.isArray(v)) flat(v, `${prefix}${k}.`, out);
      else out[`${prefix}${k}`] = JSON.stringify(v);
    }
    return out;
  };
  const flats = specs.map(s => flat(s));
  const keys = new Set(flats.flatMap(Object.keys));
  return [...keys].filter(k => flats.some(f => f[k] !== flats[0][k])).sort();
}

function showSweep(view, id) {
  document.title = `Sweep ${id} · foamd`;
  view.append(fromTemplate('tpl-sweep'));
  $('#sweep-id').textContent = id;
  const ctx = {id, y: null, data: null, chart: lineChart($('#sweep-chart'), [{id: 'y', position: 'left', title: ''}])};
  $('#sweep-y').addEventListener('change', e => {
    ctx.y = e.target.value;
    if (ctx.data) drawSweep(ctx);
  });
  poll(live => refreshSweep(live, ctx));
}

async function refreshSweep(live, ctx) {
  const [jobs, results] = await Promise.all([
    allJobs(`sweep=${enc(ctx.id)}`), getJson(`results?sweep=${enc(ctx.id)}&limit=100000`)]);
  if (!live()) return false;
  if (!jobs.length) throw new Error(`no jobs in sweep ${ctx.id}`);
  const specs = new Map(jobs.map(j => [j.id, parseSpec(j)]));
  const swept = results.swept_keys && results.swept_keys.length
    ? results.swept_keys : differingKeys([...specs.values()]);
  const keys = swept.filter(k => k !== 'seed');
  const resultsByJob = new Map((results.rows || []).map(r =>
    [r.job_id, Object.fromEntries((r.results || []).map(x => [x.name, x.value]))]));

  // One parameter set per distinct combination of the swept keys' values; seeds pool inside.
  const sets = new Map();
  for (const job of jobs) {
    const spec = specs.get(job.id);
    const values = keys.map(k => specValue(spec, k));
    const key = keys.length ? keys.map((k, i) => `${k}=${formatValue(values[i])}`).join('&') : 'all';
    if (!sets.has(key)) sets.set(key, {key, values, jobs: []});
    sets.get(key).jobs.push(job);
  }
  const ordered = [...sets.values()].sort((a, b) => {
    for (let i = 0; i < keys.length; i++) {
      const c = compareValues(a.values[i], b.values[i]);
      if (c) return c;
    }
    return 0;
  });
  ctx.data = {jobs, keys, sets: ordered, resultsByJob, specs, scene: jobs[0].scene};

  const states = jobs.map(j => stateName(j.state));
  const count = s => states.filter(x => x === s).length;
  const facts = [['scene', jobs[0].scene], ['tag', jobs[0].tag], ['swept', swept.join(', ') || '–'],
    ['jobs', jobs.length], ['succeeded', count('succeeded')], ['active', count('queued') + count('running')],
    ['failed', count('failed') + count('cancelled')]];
  $('#sweep-facts').replaceChildren(...facts.filter(([, v]) => v !== '' && v !== undefined)
    .map(([k, v]) => el('div', {}, el('dt', {}, k), el('dd', {}, String(v)))));

  const names = new Set();
  for (const r of resultsByJob.values()) Object.keys(r).forEach(n => names.add(n));
  const options = [...names].sort();
  const y = options.includes(ctx.y) ? ctx.y
    : options.includes(MAIN_RESULT[ctx.data.scene]) ? MAIN_RESULT[ctx.data.scene] : options[0] || '';
  const select = $('#sweep-y');
  if (select.options.length !== options.length) select.replaceChildren(...options.map(n => el('option', {value: n}, n)));
  select.value = y;
  ctx.y = y;

  drawSweep(ctx);
  return jobs.some(j => !j.terminal);
}

function drawSweep(ctx) {
  const {jobs, keys, sets, resultsByJob, specs} = ctx.data;
  const y = ctx.y;
  const valuesOf = set => set.jobs.map(j => (resultsByJob.get(j.id) || {})[y])
    .filter(isNum).sort((a, b) => a - b);

  // The sets' table: swept values, job counts by state, the chosen result's median and IQR.
  $('#sweep-sets thead tr').replaceChildren(...keys.map(k => el('th', {}, k)),
    ...['n', 'queued', 'running', 'succeeded', 'failed', 'cancelled'].map(c => el('th', {class: 'num'}, c)),
    el('th', {class: 'num'}, `median ${y}`), el('th', {class: 'num'}, 'IQR'));
  $('#sweep-sets tbody').replaceChildren(...sets.map(set => {
    const states = set.jobs.map(j => stateName(j.state));
    const count = s => states.filter(x => x === s).length;
    const v = valuesOf(set);
    const cell = (col, value) => el('td', {class: 'num', 'data-col': col}, value);
    return el('tr', {'data-set': set.key},
      ...keys.map((k, i) => el('td', {'data-key': k}, formatValue(set.values[i]))),
      cell('n', set.jobs.length), cell('queued', count('queued')), cell('running', count('running')),
      cell('succeeded', count('succeeded')), cell('failed', count('failed')), cell('cancelled', count('cancelled')),
      cell('median', v.length ? formatNumber(quantile(v, 0.5)) : '–'),
      cell('iqr', v.length > 1 ? `${formatNumber(quantile(v, 0.25))} – ${formatNumber(quantile(v, 0.75))}` : '–'));
  }));

  // The chart: y against the first swept key, one series per combination of the others.
  const xKey = keys[0];
  const numericX = xKey !== undefined && sets.every(s => isNum(s.values[0]));
  const xOf = set => (xKey === undefined ? 'all' : numericX ? set.values[0] : formatValue(set.values[0]));
  const seriesOf = set => keys.slice(1).map((k, i) => `${k} = ${formatValue(set.values[i + 1])}`).join(', ');
  const series = new Map();
  for (const set of sets) {
    const v = valuesOf(set);
    if (!v.length) continue;
    const name = seriesOf(set);
    if (!series.has(name)) series.set(name, []);
    series.get(name).push({x: xOf(set), median: quantile(v, 0.5), q1: quantile(v, 0.25), q3: quantile(v, 0.75)});
  }
  const chart = ctx.chart;
  chart.data.datasets = [];
  [...series.entries()].forEach(([name, pts], i) => {
    const color = COLORS[i % COLORS.length];
    const base = chart.data.datasets.length;
    chart.data.datasets.push(
      dataset(name || `median ${y}`, pts.map(p => ({x: p.x, y: p.median})), color, {pointRadius: 3.5}),
      // The interquartile band over seeds: q1 drawn invisibly, q3 filled down to it.
      {label: `${name} q1`, band: true, data: pts.map(p => ({x: p.x, y: p.q1})), borderWidth: 0, pointRadius: 0, fill: false},
      {label: `${name} q3`, band: true, data: pts.map(p => ({x: p.x, y: p.q3})), borderWidth: 0, pointRadius: 0,
        fill: {target: base + 1}, backgroundColor: `${color}2e`});
  });
  const labels = [...new Set(sets.map(xOf))];
  chart.options.scales.x = numericX
    ? {type: 'linear', title: {display: true, text: xKey}, grid: {color: '#eef0f3'}}
    : {type: 'category', labels, title: {display: true, text: xKey || ''}, grid: {color: '#eef0f3'}};
  chart.options.scales.y.title.text = `${y} (median, IQR over seeds)`;
  chart.options.plugins.legend.display = series.size > 1 || keys.length > 1;
  chart.update();
  const first = [...series.values()][0] || [];
  chart.canvas.dataset.points = JSON.stringify(first.map(p => [p.x, p.median]));
  $('#sweep-x-label').textContent = xKey ? `against ${xKey}` : '';

  // Every job of the sweep, with its set, seed, state and the chosen result.
  $('#sweep-jobs thead tr').replaceChildren(el('th', {}, 'Job'), ...keys.map(k => el('th', {}, k)),
    el('th', {class: 'num'}, 'seed'), el('th', {}, 'State'), el('th', {}, 'Outcome'), el('th', {class: 'num'}, y));
  const byJob = (a, b) => compareValues(specValue(specs.get(a.id), 'seed'), specValue(specs.get(b.id), 'seed'));
  $('#sweep-jobs tbody').replaceChildren(...sets.flatMap(set => [...set.jobs].sort(byJob).map(job => {
    const value = (resultsByJob.get(job.id) || {})[y];
    return el('tr', {'data-job-id': job.id},
      el('td', {}, el('a', {href: `#/job/${enc(job.id)}`, class: 'mono'}, job.id)),
      ...set.values.map(v => el('td', {}, formatValue(v))),
      el('td', {class: 'num'}, job.seed), el('td', {}, stateBadge(stateName(job.state))),
      el('td', {}, job.outcome || ''), el('td', {class: 'num', title: String(value ?? '')}, formatNumber(value)));
  })));
}

// ---- start ----------------------------------------------------------------------------------

function start() {
  if (typeof Chart !== 'undefined') {
    Chart.defaults.font.family = getComputedStyle(document.body).fontFamily;
    Chart.defaults.color = '#454b54';
  }
  $('#token-prompt').addEventListener('submit', e => {
    e.preventDefault();
    const t = $('#token-input').value.trim();
    if (!t) return;
    storeToken(t);
    route();
  });
  $('#forget-token').addEventListener('click', () => {
    storeToken('');
    route();
  });
  storeToken(token);
  window.addEventListener('hashchange', route);
  route();
}

start();
