// Drives headless Chromium (WebGPU on, SwiftShader's software adapter where there is no GPU)
// through the built page for scripts/web-test.sh. Checks, in the page: the thesis scene renders
// with osm at 24 channels beside exact, whose check against the closed form passed, and FLIP vs
// exact agrees with the native CLI's within 0.002; a dropped PLY of ours renders with its
// particle count; a broken file shows one line naming it and the page keeps working; a sweep
// run from the page's controls downloads results.csv and results.json in the CLI's format, with
// the CLI's cells, bytes and (within 0.002) errors. Prints key=value lines, flip_vs_exact last.
//
// A dropped numbered sequence of PLY files renders at its first frame, and steps to its last with
// that frame's particles.
//
// Two frames of an OpenVDB sequence render as a density volume.
//
//   node drive.mjs URL NATIVE_FLIP SIZE GOOD.ply PARTICLES BROKEN.ply CLI_SWEEP_DIR SEQUENCE_DIR
//                  VOLUME_SEQUENCE_DIR
import { readFileSync, readdirSync, mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromium } from 'playwright-core';

const [url, nativeFlipArg, size, goodFile, particlesArg, brokenFile, cliSweep, sequenceDir, volumeDir] = process.argv.slice(2);
const nativeFlip = Number(nativeFlipArg);
const log = [];
const fail = (what) => {
  console.error(`error: ${what}`);
  if (log.length) console.error(`browser console:\n${log.join('\n')}`);
  process.exit(1);
};

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  timeout: 60000,
  // No network beyond localhost here: Chromium's own background connections are turned off.
  args: ['--no-sandbox', '--enable-unsafe-webgpu', '--disable-gpu-sandbox', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync', '--disable-quic'],
});
try {
  const page = await browser.newPage({ acceptDownloads: true });
  page.on('console', (m) => log.push(`[${m.type()}] ${m.text()}`));
  page.on('pageerror', (e) => log.push(`[pageerror] ${e}`));
  const wait = { timeout: 15 * 60 * 1000 };
  const opened = Date.now();
  await page.goto(`${url}?technique=osm&channels=24&size=${size}`);
  await page.waitForFunction(() => window.smokeshadow && (window.smokeshadow.last || window.smokeshadow.error), null, wait);
  const first = await page.evaluate(() => ({
    last: window.smokeshadow.last,
    error: window.smokeshadow.error,
    firstImageMs: window.smokeshadow.firstImageMs,
    adapter: document.getElementById('adapter-name').textContent,
  }));
  if (first.error) fail(`the thesis scene did not render: ${first.error}`);
  const r = first.last;
  console.log(`adapter=${first.adapter}`);
  console.log(`first_image_s=${(first.firstImageMs / 1000).toFixed(1)} (page opened to first comparison drawn; ${((Date.now() - opened) / 1000).toFixed(1)} s from navigation)`);
  console.log(`osm_frame_ms=${r.technique.frame_ms} exact_frame_ms=${r.exact.frame_ms} osm_bytes=${r.technique.shadow_bytes} exact_bytes=${r.exact.shadow_bytes}`);
  console.log(`osm_passes=${JSON.stringify(r.technique.passes)}`);
  console.log(`rms_t=${r.rms_transmittance_error.toFixed(5)} reference_check=${r.exact.reference_check}`);
  if (r.technique.technique !== 'osm' || r.technique.channels_used !== 24) fail(`rendered ${r.technique.technique} at ${r.technique.channels_used} channels, not osm at 24`);
  if (`${r.width}x${r.height}` !== size) fail(`rendered ${r.width}x${r.height}, not ${size}`);
  if (!r.exact.reference_check || !r.exact.reference_check.startsWith('exact checked against the f64 closed form')) fail(`exact's self-check is missing: ${r.exact.reference_check}`);
  if (!(r.technique.shadow_bytes > 0)) fail('osm holds no shadow bytes');
  const gap = Math.abs(r.flip_mean - nativeFlip);
  console.log(`flip_native=${nativeFlip.toFixed(5)} flip_page=${r.flip_mean.toFixed(5)} difference=${gap.toFixed(5)}`);
  if (!(gap <= 0.002)) fail(`FLIP vs exact in the page, ${r.flip_mean}, is ${gap.toFixed(5)} from the CLI's ${nativeFlip} (allowed 0.002)`);

  // Every technique the thesis scene allows renders in the page (the browser's WGSL compiler,
  // Tint, is stricter than naga: this is where a shader it refuses shows), small and quick.
  // avsm is left out, and said so: on SwiftShader the GPU process runs out of memory compiling
  // its pipelines, about 130 s in, at any size (docs/web.md); everywhere else `cargo test`
  // tests it.
  const names = await page.evaluate(() => [...document.getElementById('technique').options].filter((o) => !o.disabled).map((o) => o.value));
  const rendered = [];
  for (const name of names.filter((n) => n !== 'avsm')) {
    const got = await page.evaluate((n) => window.smokeshadow.compare({ technique: n, channels: 8, size: '160x120' }), name);
    if (!got) fail(`${name} did not render in the page: ${await page.evaluate(() => window.smokeshadow.error)}`);
    if (!(got.flip_mean < 0.2)) fail(`${name}'s FLIP vs exact is ${got.flip_mean}`);
    rendered.push(`${name}:${got.flip_mean.toFixed(4)}`);
  }
  console.log(`every_technique=${rendered.join(' ')} (avsm skipped: it loses SwiftShader's device)`);

  // The sweep, from the page's controls, as scripts/web-test.sh ran the CLI's: osm and fom at
  // 24 and 8 channels, 24 bytes a texel and 3 MiB in all, at 256² and 512² maps, 3 timed
  // frames, 160x120.
  await page.evaluate(() => document.getElementById('size').add(new Option('160x120')));
  await page.selectOption('#size', '160x120');
  await page.selectOption('#sweep-techniques', ['osm', 'fom']);
  await page.fill('#sweep-channels', '24, x');
  await page.click('#sweep-run');
  const badList = await page.evaluate(() => window.smokeshadow.error);
  if (badList !== 'channels: "x" is not a whole number') fail(`a bad channel list did not give its one line: ${JSON.stringify(badList)}`);
  await page.fill('#sweep-channels', '24,8');
  await page.fill('#sweep-memory', '3 MiB, lots');
  await page.click('#sweep-run');
  await page.waitForFunction(() => window.smokeshadow.error, null, wait);
  const badSize = await page.evaluate(() => window.smokeshadow.error);
  if (!String(badSize).startsWith('memory budget "lots" is not a memory size')) fail(`a bad memory budget did not give its one line: ${JSON.stringify(badSize)}`);
  await page.fill('#sweep-memory', '3 MiB');
  await page.fill('#sweep-resolutions', '256, 512');
  await page.fill('#sweep-bytes', '24');
  await page.fill('#sweep-frames', '3');
  const sweepStarted = Date.now();
  await page.click('#sweep-run');
  await page.waitForFunction(() => window.smokeshadow.error || window.smokeshadow.lastSweep, null, wait);
  const swept = await page.evaluate(() => ({ r: window.smokeshadow.lastSweep, error: window.smokeshadow.error, status: document.getElementById('sweep-status').textContent, answers: document.querySelectorAll('#sweep-answer table').length, charts: document.querySelectorAll('#sweep-charts img').length }));
  if (swept.error) fail(`the sweep did not run in the page: ${swept.error}`);
  const sweepSeconds = (Date.now() - sweepStarted) / 1000;
  const downloaded = mkdtempSync(join(tmpdir(), 'smokeshadow-sweep-'));
  const download = async (id) => {
    const event = page.waitForEvent('download');
    await page.click(id);
    const d = await event;
    const path = join(downloaded, d.suggestedFilename());
    await d.saveAs(path);
    return readFileSync(path, 'utf8');
  };
  const pageCsv = await download('#dl-csv');
  const pageJson = JSON.parse(await download('#dl-json'));
  rmSync(downloaded, { recursive: true });
  const cliCsv = readFileSync(join(cliSweep, 'results.csv'), 'utf8');
  const cliJson = JSON.parse(readFileSync(join(cliSweep, 'results.json'), 'utf8'));
  const rows = (text) => {
    const [header, ...lines] = text.trim().split('\n');
    const columns = header.split(',');
    return { header, rows: lines.map((l) => Object.fromEntries(l.split(',').map((v, i) => [columns[i], v]))) };
  };
  const pc = rows(pageCsv);
  const cc = rows(cliCsv);
  if (pc.header !== cc.header) fail(`the page's results.csv columns differ from the CLI's:\n${pc.header}\n${cc.header}`);
  const id = (r) => `${r.technique} ${r.channels} ${r.byte_budgets} ${r.memory_budgets} ${r.shadow_res}`;
  const cliRows = new Map(cc.rows.map((r) => [id(r), r]));
  if (pc.rows.length !== cc.rows.length || !pc.rows.every((r) => cliRows.has(id(r)))) fail(`the page swept ${pc.rows.map(id).join(', ')}; the CLI ${cc.rows.map(id).join(', ')}`);
  let worst = 0;
  for (const r of pc.rows) {
    const c = cliRows.get(id(r));
    for (const k of ['channels_used', 'resident_bytes', 'persistent_bytes', 'transient_bytes', 'smoke_texels']) {
      if (r[k] !== c[k]) fail(`${id(r)}: ${k} is ${r[k]} in the page, ${c[k]} on the CLI`);
    }
    for (const k of ['flip_vs_exact', 'flip_vs_own_24', 'rms_transmittance_error']) {
      const gap = Math.abs(Number(r[k] || 0) - Number(c[k] || 0));
      if (!(gap <= 0.002)) fail(`${id(r)}: ${k} is ${r[k]} in the page, ${c[k]} on the CLI`);
      worst = Math.max(worst, gap);
    }
  }
  const keys = (o) => Object.keys(o).sort().join(',');
  if (keys(pageJson) !== keys(cliJson) || keys(pageJson.metadata) !== keys(cliJson.metadata) || keys(pageJson.cells[1]) !== keys(cliJson.cells[1])) fail('the page\'s results.json has other fields than the CLI\'s');
  // The answer at 3 MiB in all takes each technique at the map resolution tune chose for it (the
  // shipped shapes, the CLI's), and says so.
  if (JSON.stringify(pageJson.metadata.shapes) !== JSON.stringify(cliJson.metadata.shapes)) fail('the page\'s tuned shapes are not the CLI\'s');
  const atMemory = swept.r.memory_answers;
  if (atMemory.length !== 1 || atMemory[0].bytes !== 3 * 1048576 || atMemory[0].ranked.length !== 2) fail(`the page's answer at 3 MiB: ${JSON.stringify(atMemory)}`);
  for (const c of atMemory[0].ranked) {
    const chosen = cliJson.metadata.shapes[c.technique]?.[String(3 * 1048576)];
    if (c.shape_tuned !== (chosen === c.shadow_res) || (chosen && [256, 512].includes(chosen) && !c.shape_tuned)) fail(`the page answers 3 MiB with ${c.technique} at ${c.shadow_res}², tune chose ${chosen}`);
  }
  if (pageJson.cells.length !== pc.rows.length || !(pageJson.metadata.exact_check_worst < 1e-3)) fail('the page\'s results.json disagrees with its results.csv or exact did not check itself');
  if (swept.answers < 1 || swept.charts < 1) fail(`the page shows ${swept.answers} answer tables and ${swept.charts} charts`);
  console.log(`sweep_s=${sweepSeconds.toFixed(1)} (${pc.rows.length} cells and exact at 160x120, 3 frames a cell) answer_tables=${swept.answers} charts=${swept.charts}`);
  console.log(`sweep_at_3MiB: ${atMemory[0].ranked.map((c) => `${c.technique} ${c.channels_used} at ${c.shadow_res}²${c.shape_tuned ? ' (tuned)' : ' (best here)'} FLIP ${c.flip_vs_exact.toFixed(4)}`).join(', ')}`);
  console.log(`sweep_vs_cli: same columns, cells and bytes; worst |error difference| ${worst.toFixed(5)}; ${swept.status}`);

  // A dropped file of ours renders, framed as the CLI frames it.
  const input = page.locator('#files');
  await input.setInputFiles(goodFile);
  await page.waitForFunction((n) => window.smokeshadow.error || (window.smokeshadow.last && window.smokeshadow.last.particles === n && window.smokeshadow.last.scene.includes('.ply')), Number(particlesArg), wait);
  const dropped = await page.evaluate(() => ({ last: window.smokeshadow.last, error: window.smokeshadow.error }));
  if (dropped.error) fail(`the dropped ${goodFile} did not render: ${dropped.error}`);
  if (!dropped.last.exact.reference_check) fail('exact did not check itself on the dropped file');
  console.log(`dropped_file=${dropped.last.scene} flip=${dropped.last.flip_mean.toFixed(4)}`);

  // A dropped sequence: its frames to step through, each with its own particles (read here
  // from each file's PLY header).
  const frameFiles = readdirSync(sequenceDir).sort().map((f) => join(sequenceDir, f));
  const vertices = (path) => Number(/element vertex (\d+)/.exec(readFileSync(path).subarray(0, 512).toString('latin1'))[1]);
  await input.setInputFiles(frameFiles);
  await page.waitForFunction(() => window.smokeshadow.error || (window.smokeshadow.last && window.smokeshadow.last.scene.includes('%04d')), null, wait);
  const seq = await page.evaluate(() => ({ last: window.smokeshadow.last, error: window.smokeshadow.error, frames: [...document.getElementById('frame').options].map((o) => o.value), shown: !document.getElementById('frame-control').hidden }));
  if (seq.error) fail(`the dropped sequence did not render: ${seq.error}`);
  if (!seq.shown || seq.frames.length !== frameFiles.length) fail(`the page offers frames ${seq.frames} for the ${frameFiles.length} dropped files`);
  if (seq.last.particles !== vertices(frameFiles[0])) fail(`the sequence's first frame has ${seq.last.particles} particles, its file ${vertices(frameFiles[0])}`);
  const lastFrame = Number(seq.frames[seq.frames.length - 1]);
  const stepped = await page.evaluate((f) => window.smokeshadow.showFrame(f), lastFrame);
  if (!stepped) fail(`frame ${lastFrame} did not render: ${await page.evaluate(() => window.smokeshadow.error)}`);
  if (stepped.particles !== vertices(frameFiles[frameFiles.length - 1]) || stepped.particles === seq.last.particles) fail(`frame ${lastFrame} has ${stepped.particles} particles, its file ${vertices(frameFiles[frameFiles.length - 1])}`);
  console.log(`dropped_sequence=${stepped.scene}: frames ${seq.frames.join(',')}, particles ${seq.last.particles} then ${stepped.particles}, flip ${seq.last.flip_mean.toFixed(4)} then ${stepped.flip_mean.toFixed(4)}`);

  // A dropped OpenVDB sequence: a density volume, at each of its frames.
  const volumeFiles = readdirSync(volumeDir).sort().map((f) => join(volumeDir, f));
  await input.setInputFiles(volumeFiles);
  await page.waitForFunction(() => window.smokeshadow.error || (window.smokeshadow.last && window.smokeshadow.last.scene.includes('.vdb')), null, wait);
  const vol = await page.evaluate(() => ({ last: window.smokeshadow.last, error: window.smokeshadow.error, frames: [...document.getElementById('frame').options].map((o) => o.value) }));
  if (vol.error) fail(`the dropped volume sequence did not render: ${vol.error}`);
  if (vol.frames.length !== volumeFiles.length || !vol.last.scene.includes('a density volume')) fail(`the volume sequence reads ${vol.last.scene} with frames ${vol.frames}`);
  const volStep = await page.evaluate((f) => window.smokeshadow.showFrame(f), Number(vol.frames[1]));
  if (!volStep || !(volStep.flip_mean < 0.05)) fail(`the volume sequence's second frame did not render: ${await page.evaluate(() => window.smokeshadow.error)}`);
  console.log(`dropped_volume_sequence=${volStep.scene}: flip ${vol.last.flip_mean.toFixed(4)} then ${volStep.flip_mean.toFixed(4)}`);
  // Back to the particle sequence's last frame, which the broken file must not replace.
  await input.setInputFiles(frameFiles);
  await page.waitForFunction(() => window.smokeshadow.error || (window.smokeshadow.last && window.smokeshadow.last.scene.includes('%04d.ply')), null, wait);
  await page.evaluate((f) => window.smokeshadow.showFrame(f), lastFrame);

  // A broken file: one line naming it, and the page keeps working.
  await input.setInputFiles(brokenFile);
  await page.waitForFunction(() => window.smokeshadow.error, null, wait);
  const broken = await page.evaluate(() => ({ error: window.smokeshadow.error, shown: document.getElementById('error').textContent, line: document.getElementById('scene-line').textContent }));
  const name = brokenFile.split('/').pop();
  if (broken.error.includes('\n') || !broken.error.includes(name) || broken.shown !== broken.error) fail(`the broken file's message is not one line naming ${name}: ${JSON.stringify(broken.error)}`);
  console.log(`broken_file_line=${broken.error}`);
  const again = await page.evaluate(() => window.smokeshadow.compare({ technique: 'osm', channels: 8 }));
  if (!again || again.particles !== stepped.particles) fail(`after the broken file the page did not keep its scene and render: ${JSON.stringify(await page.evaluate(() => window.smokeshadow.error))}`);
  console.log('kept_working=yes');
  console.log(`flip_vs_exact=${r.flip_mean.toFixed(5)}`);
} finally {
  await browser.close();
}
