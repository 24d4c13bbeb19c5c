// The page around smokeshadow's WebAssembly core (web/src/lib.rs): controls, the three images
// and their compare modes, the numbers, dropped files. Every error is the core's one line,
// shown in #error; the page keeps working after it.
import init, { Page } from './pkg/smokeshadow_web.js';

const $ = (id) => document.getElementById(id);
const opened = performance.now();
let page = null;
let last = null; // the last comparison's summary
let showExact = false; // flip mode: which image is shown

// What tests and users can reach from the console: the page's state and its actions.
window.smokeshadow = { ready: false, last: null, lastSweep: null, error: null, firstImageMs: null, compare, sweep, openFiles, pickScene, showFrame };

function status(text) { $('status').textContent = text; }
function showError(message) {
  window.smokeshadow.error = message;
  const e = $('error');
  e.textContent = message;
  e.hidden = false;
}
function clearError() { window.smokeshadow.error = null; $('error').hidden = true; }
const message = (e) => (e && e.message) ? e.message : String(e);

async function main() {
  if (!navigator.gpu) {
    showError('This browser has no WebGPU (navigator.gpu is missing): use a recent Chrome, Edge or Safari, or Firefox with WebGPU enabled.');
    status('');
    return;
  }
  status('Loading the WebAssembly module…');
  await init();
  status('Asking the browser for its GPU…');
  try {
    page = await Page.open();
  } catch (e) {
    showError(message(e));
    status('');
    return;
  }
  // wgpu leaves a browser adapter's name empty; the browser's own adapter info has it.
  const info = await navigator.gpu.requestAdapter().then((a) => a && a.info).catch(() => null);
  showAdapter(JSON.parse(page.adapter()), info);
  for (const name of Page.scenes()) $('scene').add(new Option(name, name, name === 'thesis_plume', name === 'thesis_plume'));
  fillTechniques('osm');
  fillSweepTechniques();
  $('scene-line').textContent = page.scene();
  $('render').onclick = () => compare();
  $('sweep-run').onclick = () => sweep();
  $('scene').onchange = () => pickScene($('scene').value);
  $('mode').onchange = draw;
  $('split').oninput = draw;
  $('view-single').onclick = () => { showExact = !showExact; draw(); };
  $('files').onchange = () => openFiles([...$('files').files]);
  $('frame').onchange = () => showFrame(Number($('frame').value));
  const drop = $('drop');
  document.addEventListener('dragover', (e) => { e.preventDefault(); drop.classList.add('over'); });
  document.addEventListener('dragleave', () => drop.classList.remove('over'));
  document.addEventListener('drop', (e) => {
    e.preventDefault();
    drop.classList.remove('over');
    openFiles([...e.dataTransfer.files]);
  });
  // The controls from the address (?technique=osm&channels=24&size=512x384&scene=column), so
  // that a comparison can be linked to.
  const query = new URLSearchParams(location.search);
  if (query.has('technique')) fillTechniques(query.get('technique'));
  for (const id of ['channels', 'resolution', 'size', 'mode']) if (query.has(id)) {
    const control = $(id);
    if (control.tagName === 'SELECT' && ![...control.options].some((o) => o.value === query.get(id))) control.add(new Option(query.get(id)));
    control.value = query.get(id);
  }
  window.smokeshadow.ready = true;
  if (query.has('scene') && query.get('scene') !== 'thesis_plume') {
    $('scene').value = query.get('scene');
    await pickScene(query.get('scene'));
  } else {
    await compare();
  }
}

function fillTechniques(selected) {
  const select = $('technique');
  const keep = selected || select.value;
  select.innerHTML = '';
  for (const t of JSON.parse(page.techniques())) {
    if (t.name === 'exact') continue;
    const option = new Option(`${t.name}: ${t.description}`, t.name, false, t.name === keep);
    if (t.refusal) { option.disabled = true; option.title = t.refusal; }
    select.add(option);
  }
}

function showAdapter(a, info) {
  if (info) {
    const named = [info.vendor, info.architecture, info.device, info.description].filter(Boolean).join(' ');
    if (named) a.name = named + (info.isFallbackAdapter ? ' (a software fallback adapter)' : '');
  }
  window.smokeshadow.adapter = a.name;
  $('adapter-name').textContent = a.name;
  const rows = [['adapter', `${a.name}, ${a.device_type}, through ${a.backend}`]];
  for (const f of a.features) rows.push([f.name, f.present ? 'yes' : 'no']);
  for (const l of a.limits) rows.push([l.name, l.value.toLocaleString('en')]);
  fillTable($('adapter'), rows);
}

function fillTable(table, rows) {
  const body = table.tBodies[0];
  body.innerHTML = '';
  for (const row of rows) {
    const tr = body.insertRow();
    row.forEach((cell, i) => {
      const td = tr.insertCell();
      td.textContent = cell;
      if (i > 0 && typeof cell === 'string' && /^[\d.,\s]+(ms|MiB|KiB|B)?$/.test(cell)) td.className = 'n';
    });
  }
}

// The scene shown changes (`change` asks the page and returns its line): the controls it allows
// and its comparison, or its one line.
async function changeScene(change, frame) {
  clearError();
  try {
    $('scene-line').textContent = change();
  } catch (e) {
    showError(message(e));
    return false;
  }
  fillTechniques();
  fillSweepTechniques();
  fillFrames(frame);
  return await compare();
}

async function pickScene(name) {
  return changeScene(() => page.pick_scene(name));
}

async function openFiles(files) {
  if (!files.length) return;
  page.clear_files();
  for (const f of files) page.add_file(f.name, new Uint8Array(await f.arrayBuffer()));
  return changeScene(() => page.open_dropped());
}

// A dropped sequence's frames, to step through (hidden for anything else), `frame` shown.
function fillFrames(frame) {
  const frames = JSON.parse(page.frames());
  const select = $('frame');
  select.innerHTML = '';
  for (const f of frames) select.add(new Option(`${f}`, `${f}`));
  if (frame !== undefined) select.value = `${frame}`;
  $('frame-control').hidden = frames.length === 0;
}

async function showFrame(frame) {
  return changeScene(() => page.show_frame(frame), frame);
}

async function compare(options = {}) {
  clearError();
  const technique = options.technique || $('technique').value;
  const channels = options.channels ?? Number($('channels').value);
  const resolution = options.resolution ?? Number($('resolution').value);
  const [w, h] = (options.size || $('size').value).split('x').map(Number);
  $('render').disabled = true;
  status(`Rendering ${technique} at ${channels} channels and exact…`);
  const started = performance.now();
  try {
    last = JSON.parse(await page.compare(technique, channels, resolution, w, h));
  } catch (e) {
    showError(message(e));
    status('');
    return false;
  } finally {
    $('render').disabled = false;
  }
  window.smokeshadow.last = last;
  draw();
  if (window.smokeshadow.firstImageMs === null) window.smokeshadow.firstImageMs = performance.now() - opened;
  status(`Compared in ${((performance.now() - started) / 1000).toFixed(1)} s` +
    ` (first image ${(window.smokeshadow.firstImageMs / 1000).toFixed(1)} s after the page opened).`);
  showNumbers(last);
  return last;
}

function imageData(which) {
  return new ImageData(new Uint8ClampedArray(page.image(which)), last.width, last.height);
}

function put(canvas, data) {
  canvas.width = data.width;
  canvas.height = data.height;
  canvas.getContext('2d').putImageData(data, 0, 0);
}

function draw() {
  if (!last) return;
  const mode = $('mode').value;
  const side = mode === 'side';
  for (const id of ['view-technique', 'view-exact', 'view-flip']) $(id).parentElement.hidden = !side;
  $('single').hidden = side;
  $('split').hidden = mode !== 'split';
  $('cap-technique').textContent = `${last.technique.technique}, ${last.technique.channels_used} channels`;
  if (side) {
    put($('view-technique'), imageData('technique'));
    put($('view-exact'), imageData('exact'));
    put($('view-flip'), imageData('flip'));
    return;
  }
  const canvas = $('view-single');
  if (mode === 'flipmap') {
    put(canvas, imageData('flip'));
    $('cap-single').textContent = 'FLIP error map against exact';
  } else if (mode === 'flip') {
    put(canvas, imageData(showExact ? 'exact' : 'technique'));
    $('cap-single').textContent = `${showExact ? 'exact' : last.technique.technique} (click to swap)`;
  } else {
    const a = imageData('technique');
    const b = imageData('exact');
    const cut = Math.round(a.width * Number($('split').value) / 100);
    for (let y = 0; y < a.height; y++) {
      const row = y * a.width * 4;
      a.data.set(b.data.subarray(row + cut * 4, row + a.width * 4), row + cut * 4);
    }
    put(canvas, a);
    $('cap-single').textContent = `${last.technique.technique} left, exact right`;
  }
}

const mib = (b) => `${(b / 1048576).toFixed(2)} MiB`;
const ms = (v) => (v === null || v === undefined) ? 'no timestamps' : `${v.toFixed(2)} ms`;
// A GPU time that disagrees with the clock is not shown as a measurement (the warning says why).
const gpuMs = (f) => f.clock_warning ? `${ms(f.frame_ms)}: disagrees with the clock, read the wall time` : ms(f.frame_ms);

function showNumbers(r) {
  const t = r.technique;
  const e = r.exact;
  const passes = (p) => p ? p.map(([n, v]) => `${n} ${v.toFixed(2)}`).join(', ') : 'no timestamps';
  fillTable($('metrics'), [
    ['scene', r.scene],
    ['', t.technique, 'exact'],
    ['shadow memory (resident, scratch included)', mib(t.shadow_bytes), mib(e.shadow_bytes)],
    ['of it transient', mib(t.transient_bytes), mib(e.transient_bytes)],
    ['frame, GPU (timestamp queries)', gpuMs(t), gpuMs(e)],
    ['passes, ms', passes(t.passes), passes(e.passes)],
    ['frame, wall clock', ms(t.wall_ms), ms(e.wall_ms)],
    ['FLIP vs exact (mean)', r.flip_mean.toFixed(4)],
    ['FLIP weighted quartiles', `${r.flip_q1.toFixed(4)} / ${r.flip_median.toFixed(4)} / ${r.flip_q3.toFixed(4)}`],
    ['RMSE (sRGB) / PSNR', `${r.rmse_srgb.toFixed(4)} / ${r.psnr_db === null ? '∞' : r.psnr_db.toFixed(1) + ' dB'}`],
    ['RMS T error at the shaded points', `${r.rms_transmittance_error.toFixed(4)} (${r.shaded_points} points)`],
    ['reference', e.reference_check || ''],
    ...[t, e].filter((f) => f.clock_warning).map((f) => [`${f.technique}'s timestamps`, f.clock_warning]),
  ]);
  // Browsers may round timestamps (Chrome: to 100 µs unless started with
  // --enable-unsafe-webgpu or with "WebGPU Developer Features" on); say so when they were.
  const all = [...(t.passes || []), ...(e.passes || [])].map(([, v]) => v);
  const rounded = all.length > 0 && all.every((v) => Math.abs(v * 10 - Math.round(v * 10)) < 1e-6);
  $('timing-note').textContent = 'GPU times are WebGPU timestamp queries on this adapter; the wall clock includes the read-back. ' +
    (rounded
      ? 'This browser rounds timestamps to 0.1 ms (Chrome does unless "WebGPU Developer Features" is on in chrome://flags): passes shorter than that read as 0 or 0.1 ms.'
      : 'This browser did not round them to 0.1 ms.');
}

// The sweep's techniques: the command line's default set at first, then what the user chose,
// less what the scene refuses (its reason on hover).
function fillSweepTechniques() {
  const select = $('sweep-techniques');
  const first = select.options.length === 0;
  const chosen = new Set([...select.selectedOptions].map((o) => o.value));
  select.innerHTML = '';
  for (const t of JSON.parse(page.techniques())) {
    if (t.name === 'exact' || t.name === 'none') continue;
    const option = new Option(t.name, t.name, false, !t.refusal && (first ? t.in_default_sweep : chosen.has(t.name)));
    option.title = t.refusal || t.description;
    option.disabled = Boolean(t.refusal);
    select.add(option);
  }
}

// A comma-separated list of whole numbers, or one line naming what is not one.
function wholeNumbers(what, text) {
  const items = text.split(/[\s,]+/).filter(Boolean);
  const bad = items.find((x) => !/^\d+$/.test(x));
  if (bad !== undefined) throw new Error(`${what}: "${bad}" is not a whole number`);
  return items.map(Number);
}

let downloads = [];
async function sweep(options = {}) {
  clearError();
  let request;
  try {
    const [width, height] = (options.size || $('size').value).split('x').map(Number);
    request = {
      techniques: options.techniques || [...$('sweep-techniques').selectedOptions].map((o) => o.value),
      channels: options.channels || wholeNumbers('channels', $('sweep-channels').value),
      bytes_per_texel: options.bytes_per_texel || wholeNumbers('bytes per texel', $('sweep-bytes').value),
      // (split at commas only: "3 MiB" is one size)
      memory: options.memory || $('sweep-memory').value.split(',').map((m) => m.trim()).filter(Boolean),
      resolutions: options.resolutions || ($('sweep-resolutions').value.trim()
        ? wholeNumbers('map resolutions', $('sweep-resolutions').value)
        : [Number($('resolution').value)]),
      width, height,
      frames: options.frames ?? wholeNumbers('timed frames', $('sweep-frames').value)[0] ?? 0,
      adapter: window.smokeshadow.adapter || '',
    };
    if (!request.techniques.length) throw new Error('the sweep has no techniques: choose at least one');
  } catch (e) {
    showError(message(e));
    return false;
  }
  const bar = $('sweep-progress');
  bar.hidden = false;
  bar.value = 0;
  $('sweep-run').disabled = $('render').disabled = true;
  const started = performance.now();
  const progress = (done, total, label) => {
    bar.max = total;
    bar.value = done;
    $('sweep-status').textContent = done < total ? `Step ${done + 1} of ${total}: ${label}…` : 'Assembling the tables…';
  };
  let r;
  try {
    r = JSON.parse(await page.sweep(JSON.stringify(request), progress));
  } catch (e) {
    showError(message(e));
    $('sweep-status').textContent = '';
    return false;
  } finally {
    $('sweep-run').disabled = $('render').disabled = false;
    bar.hidden = true;
  }
  window.smokeshadow.lastSweep = r;
  showSweep(r, (performance.now() - started) / 1000);
  return r;
}

const fixed = (v, digits) => (v === null || v === undefined || !Number.isFinite(v)) ? '—' : v.toFixed(digits);

function rankTable(title, ranked) {
  const table = document.createElement('table');
  table.createCaption().textContent = title;
  const head = table.createTHead().insertRow();
  for (const h of ['', 'technique', 'channels', 'map', 'FLIP vs exact', 'RMS T error', 'resident', 'frame (GPU)', '× none']) {
    const th = document.createElement('th');
    th.textContent = h;
    head.append(th);
  }
  const body = table.createTBody();
  ranked.forEach((c, i) => {
    const tr = body.insertRow();
    const map = c.shape_tuned === false ? `${c.shadow_res}² (best here)` : `${c.shadow_res}²`;
    const cells = [`${i + 1}`, c.technique, `${c.channels_used}`, map, fixed(c.flip_vs_exact, 4), fixed(c.rms_transmittance_error, 4),
      mib(c.resident_bytes), `${fixed(c.frame_ms, 2)} ms`, fixed(c.overhead_ratio, 2)];
    cells.forEach((text, k) => {
      const td = tr.insertCell();
      td.textContent = text;
      if (k !== 1) td.className = 'n';
    });
  });
  return table;
}

function showSweep(r, seconds) {
  const answer = $('sweep-answer');
  answer.innerHTML = '';
  for (const a of r.answers) answer.append(rankTable(`At ${a.bytes_per_texel} bytes a texel: most accurate first`, a.ranked));
  for (const a of r.memory_answers) {
    answer.append(rankTable(`At ${mib(a.bytes)} in all: most accurate first, each at the map resolution tune chose on the training scenes (or, marked "best here", its most accurate here where tune chose none of those swept)`, a.ranked));
  }
  const slow = [];
  for (const a of r.time_answers) {
    if (a.ranked.length) answer.append(rankTable(`Within ${a.ratio}× the frame without self-shadowing`, a.ranked));
    else slow.push(`${a.ratio}×`);
  }
  if (slow.length) {
    const p = document.createElement('p');
    p.className = 'note';
    p.textContent = `No technique's frame took within ${slow.join(', ')} the frame without self-shadowing on this adapter.`;
    answer.append(p);
  }
  if (r.skipped.length) {
    const p = document.createElement('p');
    p.className = 'note';
    p.textContent = `Not measured: ${r.skipped.join('; ')}.`;
    answer.append(p);
  }
  for (const url of downloads) URL.revokeObjectURL(url);
  downloads = [];
  const blob = (text, type) => {
    const url = URL.createObjectURL(new Blob([text], { type }));
    downloads.push(url);
    return url;
  };
  const charts = $('sweep-charts');
  charts.innerHTML = '';
  for (const c of r.charts) {
    const figure = document.createElement('figure');
    // An image, not inline markup: the SVG names the scene, which may be a dropped file's.
    const img = document.createElement('img');
    img.src = blob(c.svg, 'image/svg+xml');
    img.alt = c.title;
    figure.append(img);
    const caption = document.createElement('figcaption');
    caption.textContent = `${c.title}: ${c.caption}`;
    figure.append(caption);
    charts.append(figure);
  }
  $('dl-csv').href = blob(r.csv, 'text/csv');
  $('dl-json').href = blob(r.json, 'application/json');
  $('sweep-downloads').hidden = false;
  $('sweep-status').textContent = `${r.cells} cells in ${seconds.toFixed(1)} s on ${r.adapter}; ${r.exact_check}.`;
}

main().catch((e) => { showError(message(e)); status(''); });
