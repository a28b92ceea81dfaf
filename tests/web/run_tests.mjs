// Browser tests of Reenact's web client against the real server.
//
//   node tests/web/run_tests.mjs --bin build/bin --web build/web [--work DIR]
//       [--chromium /usr/bin/chromium] [--keep]
//
// Makes its own data (a synthetic 2-sensor front kick, played into
// reenact-server by reenactd; a body and a rigid-cylinders job), then drives
// headless Chromium (playwright-core) through the library, the player, the
// render match against `reenact render`, the controls, the live preview and
// bad input. Prints the measured figures as one JSON line at the end; exits
// non-zero when a check fails.
//
// Needs: the npm packages of clients/web (npm ci there), Debian's chromium.
// Without --web the bundle is built into WORK/web.

import { spawn } from 'node:child_process';
import { once } from 'node:events';
import fs from 'node:fs';
import { createRequire } from 'node:module';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { gzipSync } from 'node:zlib';

const here = path.dirname(fileURLToPath(import.meta.url));
const repo = path.resolve(here, '../..');
const webPackage = path.join(repo, 'clients/web/package.json');
const requireWeb = createRequire(webPackage);
let chromium;
let PNG;
try {
  ({ chromium } = requireWeb('playwright-core'));
  ({ PNG } = requireWeb('pngjs'));
} catch (e) {
  // 77: skipped (ctest's SKIP_RETURN_CODE), saying why.
  console.error(`run_tests: SKIPPED: the packages of clients/web are missing (cd clients/web && npm ci): ${e.message}`);
  process.exit(77);
}

// ---------------------------------------------------------------- arguments

function parseArgs(argv) {
  const args = { bin: path.join(repo, 'build/bin'), web: '', work: '', chromium: '/usr/bin/chromium', keep: false, only: '' };
  for (let i = 0; i < argv.length; ++i) {
    const a = argv[i];
    const value = () => {
      if (i + 1 >= argv.length) throw new Error(`${a} needs a value`);
      return argv[++i];
    };
    if (a === '--bin') args.bin = path.resolve(value());
    else if (a === '--web') args.web = path.resolve(value());
    else if (a === '--work') args.work = path.resolve(value());
    else if (a === '--chromium') args.chromium = value();
    else if (a === '--only') args.only = value();
    else if (a === '--keep') args.keep = true;
    else if (a === '--help' || a === '-h') {
      console.log('usage: node tests/web/run_tests.mjs --bin DIR [--web DIR] [--work DIR] [--chromium PATH] [--only REGEX] [--keep]');
      process.exit(0);
    } else throw new Error(`unknown argument ${a}`);
  }
  return args;
}

const args = parseArgs(process.argv.slice(2));
if (!fs.existsSync(args.chromium)) {
  console.error(`run_tests: SKIPPED: no browser at ${args.chromium} (apt-get install chromium, or --chromium PATH)`);
  process.exit(77);
}
const W = args.work || fs.mkdtempSync(path.join(os.tmpdir(), 'reenact-web-test-'));
fs.mkdirSync(W, { recursive: true });
const bin = (name) => path.join(args.bin, name);
const figures = {};
const results = [];
const children = new Set();

function log(...a) {
  console.log(`[${new Date().toISOString().slice(11, 23)}]`, ...a);
}

// ---------------------------------------------------------------- processes

// Runs a command to its end; resolves {code, out, err}.
function run(cmd, argv, { timeoutS = 300, name = path.basename(cmd) } = {}) {
  return new Promise((resolve, reject) => {
    const child = spawn(cmd, argv, { cwd: W, stdio: ['ignore', 'pipe', 'pipe'] });
    let out = '';
    let err = '';
    child.stdout.on('data', (d) => (out += d));
    child.stderr.on('data', (d) => (err += d));
    const timer = setTimeout(() => {
      child.kill('SIGKILL');
      reject(new Error(`${name} ran past ${timeoutS} s`));
    }, timeoutS * 1000);
    child.on('error', (e) => {
      clearTimeout(timer);
      reject(e);
    });
    child.on('close', (code) => {
      clearTimeout(timer);
      fs.writeFileSync(path.join(W, `${name}.out`), out);
      fs.writeFileSync(path.join(W, `${name}.err`), err);
      resolve({ code, out, err });
    });
  });
}

async function runOk(cmd, argv, options = {}) {
  const r = await run(cmd, argv, options);
  if (r.code !== 0) throw new Error(`${path.basename(cmd)} ${argv.join(' ')} failed (${r.code}): ${r.err.slice(-1500)}`);
  return r;
}

// Starts a background process logging to W/NAME.log.
function start(name, cmd, argv) {
  const logFile = fs.openSync(path.join(W, `${name}.log`), 'a');
  const child = spawn(cmd, argv, { cwd: W, stdio: ['ignore', logFile, logFile] });
  fs.closeSync(logFile);
  child.name = name;
  child.exited = new Promise((resolve) => child.on('exit', (code, signal) => resolve({ code, signal })));
  children.add(child);
  child.exited.then(() => children.delete(child));
  return child;
}

async function stop(child, timeoutS = 20) {
  if (!child || child.exitCode !== null || child.signalCode !== null) return;
  child.kill('SIGTERM');
  const t = setTimeout(() => child.kill('SIGKILL'), timeoutS * 1000);
  await child.exited;
  clearTimeout(t);
}

const BROWSER_ARGS = ['--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'];

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function waitFor(what, fn, timeoutS, intervalMs = 100) {
  const deadline = Date.now() + timeoutS * 1000;
  let last;
  while (Date.now() < deadline) {
    try {
      last = await fn();
      if (last) return last;
    } catch (e) {
      last = e;
    }
    await sleep(intervalMs);
  }
  throw new Error(`timed out after ${timeoutS} s waiting for ${what}${last instanceof Error ? ` (${last.message})` : ''}`);
}

function readLine(file) {
  try {
    const text = fs.readFileSync(file, 'utf8');
    const nl = text.indexOf('\n');
    return nl >= 0 ? text.slice(0, nl).trim() : '';
  } catch {
    return '';
  }
}

// ---------------------------------------------------------------- checks

function check(condition, message) {
  if (!condition) throw new Error(message);
}

async function test(name, fn) {
  if (args.only && !new RegExp(args.only).test(name)) return;
  const t0 = Date.now();
  try {
    await fn();
    results.push({ name, ok: true });
    log(`PASS ${name} (${((Date.now() - t0) / 1000).toFixed(1)} s)`);
  } catch (e) {
    results.push({ name, ok: false, error: e.message });
    log(`FAIL ${name}: ${e.stack || e.message}`);
  }
}

function percentile(values, p) {
  if (!values.length) return null;
  const sorted = [...values].sort((a, b) => a - b);
  const i = Math.min(sorted.length - 1, Math.max(0, Math.ceil((p / 100) * sorted.length) - 1));
  return sorted[i];
}

// ---------------------------------------------------------------- images

function decodePng(buffer) {
  return PNG.sync.read(buffer);
}

// Pixels brighter than `threshold` in any channel (over a black background).
function silhouette(png, threshold = 10, flip = false) {
  const { width, height, data } = png;
  const mask = new Uint8Array(width * height);
  for (let y = 0; y < height; ++y) {
    for (let x = 0; x < width; ++x) {
      const i = (y * width + x) * 4;
      const on = data[i] > threshold || data[i + 1] > threshold || data[i + 2] > threshold;
      mask[y * width + (flip ? width - 1 - x : x)] = on ? 1 : 0;
    }
  }
  return { width, height, mask };
}

function iou(a, b) {
  check(a.width === b.width && a.height === b.height, `image sizes differ: ${a.width}x${a.height} vs ${b.width}x${b.height}`);
  let inter = 0;
  let union = 0;
  let na = 0;
  let nb = 0;
  for (let i = 0; i < a.mask.length; ++i) {
    const x = a.mask[i];
    const y = b.mask[i];
    if (x && y) ++inter;
    if (x || y) ++union;
    na += x;
    nb += y;
  }
  return { iou: union ? inter / union : 0, a: na, b: nb };
}

// Red: only in a; green: only in b; white: both.
function writeDiff(a, b, file) {
  const png = new PNG({ width: a.width, height: a.height });
  for (let i = 0; i < a.mask.length; ++i) {
    const x = a.mask[i];
    const y = b.mask[i];
    png.data[i * 4] = x ? 255 : 0;
    png.data[i * 4 + 1] = y ? 255 : 0;
    png.data[i * 4 + 2] = x && y ? 255 : 0;
    png.data[i * 4 + 3] = 255;
  }
  fs.writeFileSync(file, PNG.sync.write(png));
}

// ---------------------------------------------------------------- glb

// The frame instants of a reenactment .glb: the input times of an animation
// sampler with exactly frame_count keys.
function glbFrameTimes(buffer) {
  const jsonLength = buffer.readUInt32LE(12);
  const json = JSON.parse(buffer.subarray(20, 20 + jsonLength).toString('utf8'));
  const binStart = 20 + jsonLength + 8;
  const extras = json.nodes[0].extras || {};
  const frameCount = extras.frame_count;
  for (const sampler of json.animations[0].samplers) {
    const accessor = json.accessors[sampler.input];
    if (accessor.count !== frameCount) continue;
    const view = json.bufferViews[accessor.bufferView];
    const offset = binStart + (view.byteOffset || 0) + (accessor.byteOffset || 0);
    const times = [];
    for (let i = 0; i < accessor.count; ++i) times.push(buffer.readFloatLE(offset + 4 * i));
    return { times, extras };
  }
  throw new Error('the glb has no animation track with frame_count keys');
}

// ---------------------------------------------------------------- the server

const server = { grpc: '', http: '', child: null };

function serverArgs(grpc, http, extra) {
  return [
    ...extra,
    '--data', path.join(W, 'server'),
    '--listen', grpc, '--port-file', path.join(W, 'port'),
    '--http', http, '--http-port-file', path.join(W, 'http_port'),
    '--web', args.web,
  ];
}

async function startServer(grpc = '127.0.0.1:0', http = '127.0.0.1:0', extra = []) {
  for (const f of ['port', 'http_port']) fs.rmSync(path.join(W, f), { force: true });
  server.child = start('server', bin('reenact-server'), serverArgs(grpc, http, extra));
  await waitFor(
    'the server\'s port files',
    () => {
      if (server.child.exitCode !== null) throw new Error(`reenact-server exited: ${fs.readFileSync(path.join(W, 'server.log'), 'utf8').slice(-1500)}`);
      const g = readLine(path.join(W, 'port'));
      const h = readLine(path.join(W, 'http_port'));
      if (g && h) {
        server.grpc = g;
        server.http = h;
        return true;
      }
      return false;
    },
    30,
  );
  log(`reenact-server: gRPC ${server.grpc}, HTTP ${server.http}`);
}

const base = () => `http://${server.http}`;

async function reenact(argv, options) {
  return runOk(bin('reenact'), argv, options);
}

async function takes(state) {
  const r = await reenact(['takes', 'list', '--server', server.grpc, '--json', ...(state ? ['--state', state] : [])], { name: 'takes-list' });
  return JSON.parse(r.out);
}

async function submitJob(take, method, extra, name) {
  const r = await reenact(
    ['jobs', 'submit', '--server', server.grpc, '--take', take, '--method', method, ...extra, '--wait', '--json', '--quiet'],
    { timeoutS: 900, name },
  );
  const j = JSON.parse(r.out);
  check(j.job && j.job.state === 'succeeded', `${method} job did not succeed: ${r.out}`);
  return j.reenactment || j.job.reenactment_id;
}

// A live body job on a take reenactd records in real time (looped for
// `seconds`): {daemon, jobId, takeId}.
async function startLiveJob(name, seconds) {
  const daemon = start(`reenactd-${name}`, bin('reenactd'), [
    '--server', server.grpc, '--source', `playback:${path.join(W, 'source.mcap')}`, '--loop',
    '--max-seconds', String(seconds), '--once', '--take-name', name,
    '--spool', path.join(W, `spool-${name}`), '--control', '127.0.0.1:0',
  ]);
  const takeId = await waitFor(
    'a recording take',
    async () => {
      const list = await takes('recording');
      const t = list.find((x) => x.name === name);
      return t ? t.take_id : '';
    },
    30,
    50,
  );
  let submitted;
  for (let attempt = 0; attempt < 40; ++attempt) {
    const r = await run(
      bin('reenact'),
      ['jobs', 'submit', '--server', server.grpc, '--take', takeId, '--method', 'body', '--model', 'procedural', '--live', '--json'],
      { name: `submit-${name}` },
    );
    if (r.code === 0) {
      submitted = JSON.parse(r.out);
      break;
    }
    if (!/being opened|UNAVAILABLE|unavailable/.test(r.err)) throw new Error(`live submit failed: ${r.err}`);
    await sleep(50);
  }
  check(submitted, 'the live job could not be submitted');
  const jobId = submitted.job_id || (submitted.job && submitted.job.job_id);
  check(jobId, `no job id in ${JSON.stringify(submitted)}`);
  return { daemon, jobId, takeId };
}

// ---------------------------------------------------------------- the browser

let browser;
let liveBrowser;

// The live tests' browser: the tablet is another device, but here it
// shares two cores with the server's live fit; at a lower priority it takes
// only the CPU the fit leaves, as a separate device would.
async function launchLiveBrowser() {
  const wrapper = path.join(W, 'chromium-nice.sh');
  fs.writeFileSync(wrapper, `#!/bin/sh\nexec nice -n 10 ${args.chromium} "$@"\n`, { mode: 0o755 });
  return chromium.launch({ executablePath: wrapper, args: BROWSER_ARGS });
}

async function newPage(viewport = { width: 1280, height: 720 }, onBrowser = browser) {
  const context = await onBrowser.newContext({ viewport, deviceScaleFactor: 1 });
  await context.addInitScript(() => {
    window.__reenactStates = [];
    const record = () => {
      const s = document.body && document.body.dataset.state;
      const states = window.__reenactStates;
      if (s && states[states.length - 1]?.state !== s) states.push({ state: s, ms: performance.now() });
    };
    document.addEventListener('DOMContentLoaded', () => {
      record();
      new MutationObserver(record).observe(document.body, { attributes: true, attributeFilter: ['data-state'] });
    });
  });
  const page = await context.newPage();
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push(e.message));
  page.on('console', (m) => {
    if (m.type() === 'error' && process.env.REENACT_TEST_VERBOSE) log('console:', m.text());
  });
  return page;
}

async function closePage(page) {
  await page.context().close();
}

async function waitState(page, states, timeoutS = 60) {
  const list = Array.isArray(states) ? states : [states];
  await page.waitForFunction((l) => l.includes(document.body.dataset.state), list, { timeout: timeoutS * 1000 });
  return page.evaluate(() => document.body.dataset.state);
}

const twoFrames = (page) => page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));

// Waits until the body's appearance video shows instant `frame`.
async function waitAppearanceFrame(page, frame, timeoutS = 30) {
  try {
    await page.waitForFunction(
      (k) => {
        const a = window.reenactPlayer().appearance;
        return a && a.mode === 'video' && a.shown_frame === k;
      },
      frame,
      { timeout: timeoutS * 1000 },
    );
  } catch {
    const a = await page.evaluate(() => window.reenactPlayer().appearance);
    throw new Error(`the appearance video does not show frame ${frame}: ${JSON.stringify(a)}`);
  }
}

// PSNR (dB) of the colours of two RGBA PNGs over the pixels both silhouettes
// hold.
function colourPsnr(pngA, pngB, maskA, maskB) {
  let sum = 0;
  let n = 0;
  for (let i = 0; i < maskA.mask.length; ++i) {
    if (!maskA.mask[i] || !maskB.mask[i]) continue;
    for (let c = 0; c < 3; ++c) {
      const d = pngA.data[4 * i + c] - pngB.data[4 * i + c];
      sum += d * d;
    }
    n += 3;
  }
  if (n === 0) return 0;
  return 10 * Math.log10((255 * 255) / Math.max(1e-9, sum / n));
}

// The horizontal angle (degrees) of the camera about its target.
function azimuthDeg(camera) {
  return (Math.atan2(camera.eye[0] - camera.target[0], camera.eye[2] - camera.target[2]) * 180) / Math.PI;
}

// Waits until the camera stops moving (a damped drag glides on); returns
// reenactCamera() then.
async function settledCamera(page, timeoutS = 10) {
  let last = await page.evaluate(() => window.reenactCamera());
  const deadline = Date.now() + timeoutS * 1000;
  while (Date.now() < deadline) {
    await sleep(150);
    const now = await page.evaluate(() => window.reenactCamera());
    if (JSON.stringify(now.eye) === JSON.stringify(last.eye)) return now;
    last = now;
  }
  throw new Error(`the camera still moves after ${timeoutS} s`);
}

// Lit pixels (any channel above `threshold`) of a PNG over a black
// background.
function litPixels(png, threshold = 10) {
  let n = 0;
  for (let i = 0; i < png.width * png.height; ++i) {
    if (png.data[4 * i] > threshold || png.data[4 * i + 1] > threshold || png.data[4 * i + 2] > threshold) ++n;
  }
  return n;
}

// axe-core's audit of the page as it is now: its violations, each as
// {id, impact, nodes, help, targets}. The source goes in as an evaluated
// script: the server's Content-Security-Policy refuses inline ones (and
// eval), as it should.
let axeSource = '';
async function axeViolations(page) {
  axeSource = axeSource || fs.readFileSync(requireWeb.resolve('axe-core/axe.min.js'), 'utf8');
  await page.evaluate(axeSource);
  return page.evaluate(async () => {
    const result = await window.axe.run(document, { resultTypes: ['violations'] });
    return result.violations.map((v) => ({
      id: v.id,
      impact: v.impact,
      nodes: v.nodes.length,
      help: v.help,
      targets: v.nodes.slice(0, 3).map((n) => n.target.join(' ')),
    }));
  });
}

async function seekTo(page, t) {
  await page.evaluate((x) => {
    const s = document.getElementById('scrub');
    s.value = String(x);
    s.dispatchEvent(new Event('input', { bubbles: true }));
  }, t);
}

// Media-time rate (media seconds per wall second) over `ms`, measured in
// the page.
function mediaRate(page, ms) {
  return page.evaluate(
    (duration) =>
      new Promise((resolve) => {
        const p0 = window.reenactPlayer();
        let last = p0.time;
        let media = 0;
        const t0 = performance.now();
        const timer = setInterval(() => {
          const t = window.reenactPlayer().time;
          let d = t - last;
          if (d < 0) d += p0.duration;
          media += d;
          last = t;
          if (performance.now() - t0 >= duration) {
            clearInterval(timer);
            resolve(media / ((performance.now() - t0) / 1000));
          }
        }, 20);
      }),
    ms,
  );
}

// ---------------------------------------------------------------- tests

async function main() {
  log(`work folder ${W}`);
  for (const name of ['reenact', 'reenact-server', 'reenactd', 'reenact-worker']) {
    check(fs.existsSync(bin(name)), `no ${bin(name)}`);
  }
  if (!args.web) {
    args.web = path.join(W, 'web');
    await runOk(process.execPath, [path.join(repo, 'clients/web/build.mjs'), '--outdir', args.web], { name: 'build' });
  }
  check(fs.existsSync(path.join(args.web, 'index.html')), `no index.html in ${args.web}`);
  {
    let gz = 0;
    let raw = 0;
    for (const f of ['index.html', 'app.js', 'app.css']) {
      const b = fs.readFileSync(path.join(args.web, f));
      raw += b.length;
      gz += gzipSync(b, { level: 9 }).length;
    }
    figures.bundle_bytes = raw;
    figures.bundle_gzip_bytes = gz;
  }
  const help = await run(bin('reenact-server'), ['--help'], { name: 'server-help' });
  check(/--http\b/.test(help.out + help.err), 'reenact-server has no --http');

  // ---- data
  log('synthesising the take');
  await reenact(['synth', '--motion', 'builtin:front-kick', '--body', 'procedural', '--sensors', '2', '--seconds', '3', '--out', path.join(W, 'source.mcap')], { name: 'synth', timeoutS: 600 });
  await startServer();
  log('recording the take (reenactd --fast)');
  await runOk(bin('reenactd'), [
    '--server', server.grpc, '--source', `playback:${path.join(W, 'source.mcap')}`, '--once', '--fast',
    '--take-name', 'front-kick', '--spool', path.join(W, 'spool'), '--control', '127.0.0.1:0',
  ], { name: 'reenactd', timeoutS: 300 });
  const takeId = (await takes()).find((t) => t.name === 'front-kick').take_id;
  log(`take ${takeId}; body and rigid-cylinders jobs`);
  const bodyId = await submitJob(takeId, 'body', ['--model', 'procedural'], 'job-body');
  const rigidId = await submitJob(takeId, 'rigid-cylinders', [], 'job-rigid');
  log(`reenactments: body ${bodyId}, rigid ${rigidId}`);
  const glbs = {};
  let liveJobId = '';
  for (const [kind, id] of [['body', bodyId], ['rigid', rigidId]]) {
    const r = await fetch(`${base()}/api/v1/reenactments/${id}/model.glb`);
    check(r.ok, `model.glb of ${id}: HTTP ${r.status}`);
    const buffer = Buffer.from(await r.arrayBuffer());
    glbs[kind] = { id, buffer, ...glbFrameTimes(buffer) };
  }
  figures.body_glb_bytes = glbs.body.buffer.length;
  figures.rigid_glb_bytes = glbs.rigid.buffer.length;

  browser = await chromium.launch({ executablePath: args.chromium, args: BROWSER_ARGS });

  // ---- library
  await test('library lists both reenactments with their facts and stills', async () => {
    const page = await newPage({ width: 1280, height: 800 });
    await page.goto(`${base()}/`);
    await waitState(page, ['ready', 'error']);
    check((await page.evaluate(() => document.body.dataset.state)) === 'ready', `library state: ${await page.textContent('#error')}`);
    const cards = await page.$$eval('.card[data-id]', (els) =>
      els.map((e) => ({ id: e.dataset.id, method: e.querySelector('.method').textContent, frames: e.querySelector('.frames').textContent, length: e.querySelector('.length').textContent })),
    );
    for (const id of [bodyId, rigidId]) check(cards.some((c) => c.id === id), `no card for ${id}: ${JSON.stringify(cards)}`);
    const body = cards.find((c) => c.id === bodyId);
    check(body.method === 'body' && body.frames === '90', `body card: ${JSON.stringify(body)}`);
    check(cards.find((c) => c.id === rigidId).method === 'rigid-cylinders', 'rigid card method');
    await page.waitForFunction(() => document.querySelectorAll('.still img').length >= 2, null, { timeout: 60000 });
    await page.screenshot({ path: path.join(W, 'library.png') });
    check(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
    await closePage(page);
  });

  await test('library cards are titled by method and take, with the date and the uploaded file', async () => {
    const page = await newPage({ width: 1024, height: 768 });
    // The rigid reenactment's take as if uploaded from a file.
    const file = 'coach-anna_squats.mcap';
    await page.route(/\/api\/v1\/reenactments\?/, async (route) => {
      const response = await route.fetch();
      const list = (await response.json()).map((r) => (r.id === rigidId ? { ...r, take_name: file } : r));
      await route.fulfill({ response, json: list });
    });
    await page.goto(`${base()}/`);
    check((await waitState(page, ['ready', 'error'])) === 'ready', 'library not ready');
    const cards = await page.$$eval('.card[data-id]', (els) =>
      els.map((e) => ({
        id: e.dataset.id,
        title: e.querySelector('.card-title').textContent,
        when: e.querySelector('.card-when')?.textContent || '',
        file: e.querySelector('.card-file')?.textContent || '',
      })),
    );
    const body = cards.find((c) => c.id === bodyId);
    const rigid = cards.find((c) => c.id === rigidId);
    log(`card titles: "${body.title}" (${body.when}); "${rigid.title}" (${rigid.when}; ${rigid.file})`);
    check(body.title === 'Body · front-kick', `body card title "${body.title}"`);
    check(/\d/.test(body.when), `body card date "${body.when}"`);
    check(body.file === '', `a recorded take shows a file: "${body.file}"`);
    check(rigid.title === 'Rigid cylinders · coach-anna squats', `uploaded take's card title "${rigid.title}"`);
    check(!rigid.title.includes('.mcap'), 'the title shows the file name');
    check(rigid.file.includes(file), `the file name is not kept as secondary text: "${rigid.file}"`);
    check(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
    await closePage(page);
  });

  await test('an empty library says how to make a reenactment', async () => {
    const page = await newPage({ width: 1024, height: 768 });
    await page.route(/\/api\/v1\/reenactments\?/, (route) => route.fulfill({ status: 200, contentType: 'application/json', body: '[]' }));
    await page.goto(`${base()}/`);
    check((await waitState(page, ['ready', 'error'])) === 'ready', 'library not ready');
    check(await page.isVisible('#empty-note'), 'no note for an empty library');
    const text = await page.innerText('#empty-note');
    log(`empty library says: ${text.replace(/\s+/g, ' ')}`);
    for (const says of [/No reenactments yet/, /reenact takes upload/, /reenactd/, /reenact jobs submit .*--take/, /README/]) {
      check(says.test(text), `the note does not say ${says}: "${text}"`);
    }
    check((await page.$$('.card')).length === 0, 'cards in an empty library');
    await closePage(page);
  });

  await test('a reenactment is as long on its card as in the player (frames / fps)', async () => {
    const page = await newPage({ width: 1024, height: 768 });
    await page.goto(`${base()}/`);
    check((await waitState(page, ['ready', 'error'])) === 'ready', 'library not ready');
    const lengths = {};
    for (const kind of ['body', 'rigid']) {
      const { id, extras } = glbs[kind];
      const card = (await page.textContent(`.card[data-id="${id}"] .length`)).trim();
      const title = await page.textContent(`.card[data-id="${id}"] .card-title`);
      lengths[kind] = { card, title, expected: `${(extras.frame_count / extras.fps).toFixed(2)} s` };
    }
    for (const kind of ['body', 'rigid']) {
      const { id } = glbs[kind];
      await page.goto(`${base()}/?reenactment=${id}&paused=1&t=0.5`);
      check((await waitState(page, ['ready', 'error'])) === 'ready', 'player not ready');
      await page.waitForFunction(() => / s · /.test(document.getElementById('subtitle').textContent), null, { timeout: 10000 });
      const readout = await page.textContent('#time');
      const subtitle = await page.textContent('#subtitle');
      const p = await page.evaluate(() => window.reenactPlayer());
      lengths[kind].readout = readout;
      lengths[kind].subtitle = subtitle;
      lengths[kind].timeline_end_s = p.duration;
      const { card, expected } = lengths[kind];
      log(`${kind}: card ${card}, player "${readout}", subtitle "${subtitle}", frames/fps ${expected}, last frame at ${p.duration.toFixed(3)} s`);
      check(card === expected, `${kind}: the card says ${card}, frames / fps is ${expected}`);
      check(readout.endsWith(`/ ${card}`), `${kind}: the player says "${readout}", the card ${card}`);
      check(subtitle.includes(card), `${kind}: the player's subtitle "${subtitle}" lacks ${card}`);
      check(Math.abs(p.length_s - Number.parseFloat(card)) < 0.006, `${kind}: reenactPlayer().length_s ${p.length_s}`);
      // The player is titled as the card is.
      const title = await page.textContent('#title');
      check(title === lengths[kind].title, `${kind}: the player's title "${title}", the card's "${lengths[kind].title}"`);
    }
    figures.lengths = lengths;
    check(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
    await closePage(page);
  });

  // ---- play
  for (const kind of ['body', 'rigid']) {
    await test(`${kind} reenactment plays and its frames advance`, async () => {
      const page = await newPage();
      await page.goto(`${base()}/?reenactment=${glbs[kind].id}`);
      const state = await waitState(page, ['playing', 'error']);
      check(state === 'playing', `state ${state}: ${await page.textContent('#error')}`);
      const s0 = await page.evaluate(() => window.reenactStats());
      await sleep(1200);
      const s1 = await page.evaluate(() => window.reenactStats());
      check(s1.frames === glbs[kind].extras.frame_count, `frames ${s1.frames}`);
      check(s1.frame !== s0.frame, `frame stayed at ${s0.frame}`);
      check(s1.fps > 0, `fps ${s1.fps}`);
      const readyAt = await page.evaluate(() => window.__reenactStates.find((s) => s.state === 'ready' || s.state === 'playing')?.ms);
      figures[`${kind}_time_to_first_frame_ms`] = Math.round(readyAt);
      check(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
      await closePage(page);
    });
  }

  // ---- render match
  const K = 30; // frame index shown (t = its instant)
  for (const kind of ['body', 'rigid']) {
    await test(`${kind}: the page's image matches reenact render from the same camera`, async () => {
      const { id, times } = glbs[kind];
      const t = times[K];
      const page = await newPage({ width: 960, height: 540 });
      await page.goto(`${base()}/?reenactment=${id}&t=${t}&paused=1&yaw=0&mirror=0&bg=000000&controls=0&floor=0`);
      const state = await waitState(page, ['ready', 'error']);
      check(state === 'ready', `state ${state}: ${await page.textContent('#error')}`);
      if (kind === 'body') await waitAppearanceFrame(page, K);
      await twoFrames(page);
      const camera = await page.evaluate(() => window.reenactCamera());
      const frame = (await page.evaluate(() => window.reenactStats())).frame;
      check(frame === K, `frame ${frame}, wanted ${K}`);
      check(camera.width === 960 && camera.height === 540, `canvas ${camera.width}x${camera.height}`);
      const shot = await page.locator('#view').screenshot();
      fs.writeFileSync(path.join(W, `${kind}-page.png`), shot);
      await closePage(page);
      const cameraFile = path.join(W, `${kind}-camera.json`);
      fs.writeFileSync(cameraFile, JSON.stringify({ origin: 'world', fov_deg: camera.hfov_deg, keys: [{ step: 0, frame, eye: camera.eye, target: camera.target }] }, null, 1));
      const out = path.join(W, `${kind}-render`);
      fs.rmSync(out, { recursive: true, force: true });
      await reenact(['render', '--server', server.grpc, '--reenactment', id, '--camera', `path:${cameraFile}`, '--width', String(camera.width), '--height', String(camera.height), '--out', out, '--mode', 'baked', '--quiet'], { name: `render-${kind}`, timeoutS: 300 });
      const pngs = fs.readdirSync(out).filter((f) => f.endsWith('.png'));
      check(pngs.length === 1, `reenact render wrote ${pngs.join(',') || 'nothing'}`);
      const a = silhouette(decodePng(shot));
      const b = silhouette(decodePng(fs.readFileSync(path.join(out, pngs[0]))));
      const r = iou(a, b);
      writeDiff(a, b, path.join(W, `${kind}-silhouettes.png`));
      figures[`${kind}_render_iou`] = Number(r.iou.toFixed(4));
      log(`${kind}: silhouette IoU ${r.iou.toFixed(4)} (page ${r.a} px, render ${r.b} px)`);
      check(r.a > 2000, `the page drew only ${r.a} pixels`);
      check(r.iou >= 0.9, `silhouette IoU ${r.iou.toFixed(4)} < 0.9`);
      if (kind === 'body') {
        // Colour where both drew the body: both show the instant's atlas
        // from the appearance video.
        const psnr = colourPsnr(decodePng(shot), decodePng(fs.readFileSync(path.join(out, pngs[0]))), a, b);
        figures.body_render_psnr_db = Number(psnr.toFixed(2));
        log(`body: colour PSNR page vs reenact render ${psnr.toFixed(2)} dB`);
        check(psnr >= 20, `colour PSNR ${psnr.toFixed(2)} dB < 20 dB`);
      }
    });
  }

  // ---- controls
  await test('pause holds the frame', async () => {
    const page = await newPage();
    await page.goto(`${base()}/?reenactment=${bodyId}`);
    check((await waitState(page, ['playing', 'error'])) === 'playing', 'not playing');
    await sleep(300);
    await page.click('#play');
    await waitState(page, 'ready', 5);
    const f0 = await page.evaluate(() => [window.reenactStats().frame, window.reenactPlayer().time]);
    await sleep(1000);
    const f1 = await page.evaluate(() => [window.reenactStats().frame, window.reenactPlayer().time]);
    check(f0[0] === f1[0] && f0[1] === f1[1], `paused frame moved: ${f0} -> ${f1}`);
    await page.click('#play');
    await waitState(page, 'playing', 5);
    await sleep(800);
    const f2 = await page.evaluate(() => window.reenactStats().frame);
    check(f2 !== f1[0], 'play did not resume');
    await closePage(page);
  });

  await test('2x speed advances twice as fast as 1x', async () => {
    const page = await newPage();
    await page.goto(`${base()}/?reenactment=${bodyId}`);
    check((await waitState(page, ['playing', 'error'])) === 'playing', 'not playing');
    await sleep(500);
    const r1 = await mediaRate(page, 3000);
    await page.selectOption('#speed', '2');
    await sleep(300);
    const r2 = await mediaRate(page, 3000);
    await page.selectOption('#speed', '0.25');
    await sleep(300);
    const rq = await mediaRate(page, 3000);
    figures.media_rate_1x = Number(r1.toFixed(3));
    figures.media_rate_2x = Number(r2.toFixed(3));
    figures.media_rate_025x = Number(rq.toFixed(3));
    log(`media time rate: 1x ${r1.toFixed(3)}, 2x ${r2.toFixed(3)}, 0.25x ${rq.toFixed(3)}`);
    check(Math.abs(r1 - 1) <= 0.2, `1x plays at ${r1.toFixed(3)}`);
    check(Math.abs(r2 / r1 - 2) <= 0.4, `2x / 1x = ${(r2 / r1).toFixed(3)}`);
    check(Math.abs(rq / r1 - 0.25) <= 0.05, `0.25x / 1x = ${(rq / r1).toFixed(3)}`);
    await closePage(page);
  });

  await test('body: the appearance video keeps in step at 1x, 2x, 0.25x, on seek and while paused', async () => {
    const page = await newPage({ width: 1024, height: 768 });
    await page.goto(`${base()}/?reenactment=${bodyId}`);
    check((await waitState(page, ['playing', 'error'])) === 'playing', 'not playing');
    await page.waitForFunction(() => window.reenactPlayer().appearance?.mode === 'video', null, { timeout: 30000 });
    // The share of drawn frames whose video frame is within one of the
    // animation's, per speed.
    const inStep = async (ms) => {
      const a0 = await page.evaluate(() => window.reenactPlayer().appearance);
      await sleep(ms);
      const a1 = await page.evaluate(() => window.reenactPlayer().appearance);
      const ticks = a1.ticks - a0.ticks;
      return {
        share: ticks > 0 ? (a1.in_step - a0.in_step) / ticks : 0,
        offset: ticks > 0 ? (a1.offset_sum - a0.offset_sum) / ticks : 99,
        presented: a1.presented - a0.presented,
        ticks,
        seeks: a1.seeks - a0.seeks,
      };
    };
    // Each speed is measured after a second to settle.
    await sleep(1000);
    const s1 = await inStep(3000);
    await page.selectOption('#speed', '2');
    await sleep(1000);
    const s2 = await inStep(3000);
    await page.selectOption('#speed', '0.25');
    await sleep(1000);
    const sq = await inStep(3000);
    const rows = [['1x', 1, s1], ['2x', 2, s2], ['0.25x', 0.25, sq]];
    for (const [speed, , r] of rows) {
      figures[`appearance_in_step_${speed}`] = Number(r.share.toFixed(3));
      figures[`appearance_offset_frames_${speed}`] = Number(r.offset.toFixed(2));
      log(`appearance video at ${speed}: ${(100 * r.share).toFixed(1)} % of drawn frames within a frame of the animation's, ` +
        `mean offset ${r.offset.toFixed(2)} frames (${r.ticks} drawn, ${r.presented} video frames presented, ${r.seeks} seeks)`);
    }
    // The browser presents the video's frames at its own pace P (on this
    // machine's software decoder and compositor, 13-18 a second), so at
    // speed s a presented frame stands for s x fps / P of the animation's
    // and is on average half that off even when the sync is right: the
    // bound is that, measured, plus one frame.
    const takeFps = glbs.body.extras.fps;
    for (const [speed, x, r] of rows) {
      check(r.presented >= 5, `${speed}: only ${r.presented} video frames presented`);
      const bound = 1 + (0.5 * x * takeFps) / (r.presented / 3);
      check(r.offset <= bound, `${speed}: the drawn video frame is ${r.offset.toFixed(2)} frames off on average (bound ${bound.toFixed(2)})`);
    }
    // Paused: a seek, then frame steps, each shown exactly.
    await page.click('#play');
    await seekTo(page, 2.0);
    let frame = (await page.evaluate(() => window.reenactStats())).frame;
    await waitAppearanceFrame(page, frame, 10);
    for (const key of ['ArrowRight', 'ArrowRight', 'ArrowLeft']) {
      await page.keyboard.press(key);
      frame = (await page.evaluate(() => window.reenactStats())).frame;
      await waitAppearanceFrame(page, frame, 10);
    }
    await seekTo(page, 0);
    await waitAppearanceFrame(page, 0, 10);
    const fps = [];
    await page.click('#play');
    await sleep(1000);
    for (let i = 0; i < 3; ++i) {
      await sleep(1000);
      fps.push((await page.evaluate(() => window.reenactStats())).fps);
    }
    figures.page_fps_1024x768_appearance_video = percentile(fps, 50);
    log(`page fps at 1024x768 with the appearance video: ${fps.join(', ')}`);
    check(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
    await closePage(page);
  });

  for (const [what, setup, says] of [
    ['none on the server', (page) => page.route('**/appearance.mp4*', (route) => route.fulfill({ status: 404, contentType: 'application/json', body: JSON.stringify({ error: { code: 'NOT_FOUND', message: 'no appearance video' } }) })), /no appearance video/],
    ['not a video', (page) => page.route('**/appearance.mp4*', (route) => route.fulfill({ status: 200, contentType: 'video/mp4', body: Buffer.from('this is not an MP4 file, only text') })), /does not play/],
    // The server's video cut in half: its index promises every frame, its
    // data holds the first half.
    ['truncated', (page) => page.route('**/appearance.mp4*', async (route) => {
      const whole = await (await route.fetch({ headers: { ...route.request().headers(), range: 'bytes=0-' } })).body();
      await route.fulfill({ status: 200, contentType: 'video/mp4', body: whole.subarray(0, Math.floor(whole.length / 2)) });
    }), /stopped decoding|stalled|does not play/],
    ['no H.264 in the browser', (page) => page.addInitScript(() => {
      HTMLMediaElement.prototype.canPlayType = () => '';
    }), /cannot decode H\.264/],
  ]) {
    await test(`body appearance video ${what}: the static atlas, and the note says why`, async () => {
      const page = await newPage();
      await setup(page);
      await page.goto(`${base()}/?reenactment=${bodyId}`);
      check((await waitState(page, ['playing', 'error'])) === 'playing', 'not playing');
      await page.waitForFunction(() => window.reenactPlayer().appearance?.mode === 'atlas', null, { timeout: 30000 });
      const note = await page.textContent('#appearance-note');
      log(`appearance ${what}: ${note}`);
      check(says.test(note), `note "${note}"`);
      const s0 = await page.evaluate(() => window.reenactStats());
      await sleep(700);
      check((await page.evaluate(() => window.reenactStats())).frame !== s0.frame, 'the animation stopped');
      check(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
      await closePage(page);
    });
  }

  await test('A-B loop repeats A..B', async () => {
    const page = await newPage();
    await page.goto(`${base()}/?reenactment=${bodyId}&paused=1`);
    check((await waitState(page, ['ready', 'error'])) === 'ready', 'not ready');
    const A = 0.8;
    const B = 1.6;
    await seekTo(page, A);
    await page.click('#set-a');
    await seekTo(page, B);
    await page.click('#set-b');
    const ab = await page.evaluate(() => window.reenactPlayer());
    check(Math.abs(ab.a - A) < 1e-6 && Math.abs(ab.b - B) < 1e-6, `A-B ${ab.a}..${ab.b}`);
    await page.click('#play');
    await waitState(page, 'playing', 5);
    const samples = await page.evaluate(
      () =>
        new Promise((resolve) => {
          const s = [];
          const timer = setInterval(() => {
            s.push(window.reenactPlayer().time);
            if (s.length >= 150) {
              clearInterval(timer);
              resolve(s);
            }
          }, 20);
        }),
    );
    const outside = samples.filter((t) => t < A - 1e-6 || t > B + 1e-6);
    let wraps = 0;
    for (let i = 1; i < samples.length; ++i) if (samples[i] < samples[i - 1] - 0.2) ++wraps;
    check(outside.length === 0, `times outside [A, B]: ${outside.slice(0, 5)}`);
    check(wraps >= 2, `the loop wrapped ${wraps} times in 3 s`);
    await page.click('#clear-ab');
    check((await page.evaluate(() => window.reenactPlayer().a)) === null, 'A-B not cleared');
    await closePage(page);
  });

  await test('the A-B loop buttons say what they do, on screen and by name', async () => {
    for (const viewport of [{ width: 1024, height: 768 }, { width: 390, height: 844 }]) {
      const page = await newPage(viewport);
      await page.goto(`${base()}/?reenactment=${bodyId}&paused=1`);
      check((await waitState(page, ['ready', 'error'])) === 'ready', 'not ready');
      if (await page.isVisible('#more')) await page.click('#more');
      const seen = [];
      for (const [id, name] of [['set-a', 'Loop start'], ['set-b', 'Loop end'], ['clear-ab', 'Clear loop']]) {
        check(await page.isVisible(`#${id}`), `#${id} is not visible at ${viewport.width}x${viewport.height}`);
        const text = (await page.innerText(`#${id}`)).trim();
        const byName = await page.getByRole('button', { name, exact: true }).evaluateAll((els) => els.map((e) => e.id));
        seen.push(`#${id} "${text}"`);
        check(text === name, `#${id} shows "${text}", wanted "${name}"`);
        check(byName.length === 1 && byName[0] === id, `the button named "${name}" is ${JSON.stringify(byName)}`);
      }
      log(`A-B buttons at ${viewport.width}x${viewport.height}: ${seen.join(', ')}`);
      await closePage(page);
    }
  });

  await test('Space and Enter press a focused control and leave playback alone', async () => {
    const page = await newPage({ width: 1280, height: 720 });
    await page.goto(`${base()}/?reenactment=${bodyId}&paused=1&t=0.5`);
    check((await waitState(page, ['ready', 'error'])) === 'ready', 'not ready');
    const playing = () => page.evaluate(() => window.reenactPlayer().playing);
    // On the page itself Space still plays and pauses.
    await page.evaluate(() => document.activeElement && document.activeElement.blur());
    await page.keyboard.press('Space');
    check((await waitState(page, 'playing', 5)) === 'playing', 'Space on the page does not play');
    await page.keyboard.press('Space');
    check((await waitState(page, 'ready', 5)) === 'ready', 'Space on the page does not pause');
    await seekTo(page, 0.5);
    const outcomes = [];
    // Space and Enter on the mirror button: mirrored, then not; still paused.
    for (const [key, pressed] of [['Space', 'true'], ['Enter', 'false']]) {
      await page.focus('#mirror');
      await page.keyboard.press(key);
      await sleep(150);
      const now = await page.getAttribute('#mirror', 'aria-pressed');
      outcomes.push(`${key} on Mirror: aria-pressed ${now}, playing ${await playing()}`);
      check(now === pressed, `${key} on Mirror left aria-pressed ${now}`);
      check(!(await playing()), `${key} on Mirror toggled playback`);
    }
    // Enter and Space on Loop start / Loop end set the loop, once.
    await page.focus('#set-a');
    await page.keyboard.press('Enter');
    await seekTo(page, 1.5);
    await page.focus('#set-b');
    await page.keyboard.press('Space');
    await sleep(150);
    const ab = await page.evaluate(() => window.reenactPlayer());
    outcomes.push(`Enter on Loop start, Space on Loop end: A-B ${ab.a}..${ab.b}, playing ${ab.playing}`);
    check(Math.abs(ab.a - 0.5) < 1e-6 && Math.abs(ab.b - 1.5) < 1e-6, `A-B ${ab.a}..${ab.b}`);
    check(!ab.playing, 'Space on Loop end toggled playback');
    // Space on the play button plays once (not twice, which would pause).
    await page.focus('#play');
    await page.keyboard.press('Space');
    await sleep(300);
    outcomes.push(`Space on Play: playing ${await playing()}`);
    check(await playing(), 'Space on the play button did not play (or toggled twice)');
    await page.keyboard.press('Space');
    await sleep(300);
    check(!(await playing()), 'Space on the pause button did not pause');
    // Space on the time slider, the speed list and a link: no toggle.
    for (const selector of ['#scrub', '#speed', '.back']) {
      await page.focus(selector);
      await page.keyboard.press('Space');
      await sleep(150);
      outcomes.push(`Space on ${selector}: playing ${await playing()}`);
      check(!(await playing()), `Space on ${selector} toggled playback`);
      await page.keyboard.press('Escape');
    }
    check(page.url().includes('reenactment='), `a key left the player: ${page.url()}`);
    log(outcomes.join('; '));
    check(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
    await closePage(page);
  });

  await test('mirror flips the image', async () => {
    const shots = [];
    const drags = [];
    for (const mirror of [0, 1]) {
      const page = await newPage({ width: 960, height: 540 });
      await page.goto(`${base()}/?reenactment=${bodyId}&t=${glbs.body.times[K]}&paused=1&yaw=0&mirror=${mirror}&bg=000000&controls=0&floor=0`);
      check((await waitState(page, ['ready', 'error'])) === 'ready', 'not ready');
      await twoFrames(page);
      const cam = await page.evaluate(() => window.reenactCamera());
      check(cam.mirror === (mirror === 1), `reenactCamera().mirror ${cam.mirror}`);
      shots.push(await page.locator('#view').screenshot());
      // A drag to the right: the camera orbits one way in the plain image
      // and the other in the mirror (so the picture moves with the finger).
      await page.mouse.move(480, 270);
      await page.mouse.down();
      await page.mouse.move(560, 270, { steps: 8 });
      await page.mouse.up();
      drags.push((await page.evaluate(() => window.reenactCamera())).eye[0] - cam.eye[0]);
      await closePage(page);
    }
    log(`drag right: eye x moved ${drags[0].toFixed(3)} m plain, ${drags[1].toFixed(3)} m mirrored`);
    check(Math.abs(drags[0]) > 0.1 && Math.sign(drags[0]) === -Math.sign(drags[1]), 'the drag does not follow the mirror');
    fs.writeFileSync(path.join(W, 'mirror-0.png'), shots[0]);
    fs.writeFileSync(path.join(W, 'mirror-1.png'), shots[1]);
    const plain = decodePng(shots[0]);
    const flipped = silhouette(plain, 10, true);
    const straight = silhouette(plain, 10, false);
    const mirrored = silhouette(decodePng(shots[1]));
    const r = iou(flipped, mirrored);
    const unflipped = iou(straight, mirrored);
    figures.mirror_iou = Number(r.iou.toFixed(4));
    log(`mirror: IoU with the flipped image ${r.iou.toFixed(4)}, with the unflipped ${unflipped.iou.toFixed(4)}`);
    check(r.iou >= 0.95, `mirror IoU ${r.iou.toFixed(4)} < 0.95`);
    check(unflipped.iou < r.iou, 'the mirrored image is no closer to the flipped one than to the original');
  });

  await test('yaw turns the teacher, Face me faces the camera, AR says why it is off', async () => {
    const page = await newPage({ width: 960, height: 540 });
    await page.goto(`${base()}/?reenactment=${bodyId}&t=1&paused=1&yaw=90`);
    check((await waitState(page, ['ready', 'error'])) === 'ready', 'not ready');
    check((await page.evaluate(() => window.reenactPlayer().yaw_deg)) === 90, 'yaw from the link');
    await page.click('#face-me');
    const yaw = await page.evaluate(() => window.reenactPlayer().yaw_deg);
    check(Math.abs(yaw) < 5, `Face me turned to ${yaw} (the default camera is in front)`);
    // Headless Chromium has no immersive-ar: the button is off and says why.
    await page.waitForFunction(() => document.getElementById('ar-note').textContent.length > 0, null, { timeout: 5000 });
    check(await page.isDisabled('#ar-place'), 'Place (AR) is enabled without immersive-ar');
    log(`AR: "${await page.textContent('#ar-note')}"`);
    await closePage(page);
  });

  await test('the floor grid: at y = 0 by default, off with &floor=0 and with its button', async () => {
    const url = `${base()}/?reenactment=${bodyId}&t=1&paused=1&yaw=0&bg=000000`;
    const page = await newPage({ width: 960, height: 540 });
    await page.goto(url);
    check((await waitState(page, ['ready', 'error'])) === 'ready', 'not ready');
    await twoFrames(page);
    const cam = await page.evaluate(() => window.reenactCamera());
    check(cam.floor.visible && cam.floor.y === 0, `floor ${JSON.stringify(cam.floor)}`);
    check((await page.getAttribute('#floor', 'aria-pressed')) === 'true', 'the Floor button is not pressed');
    const withFloor = litPixels(decodePng(await page.locator('#view').screenshot()));
    await page.click('#floor');
    await twoFrames(page);
    check(!(await page.evaluate(() => window.reenactPlayer().floor)), 'the Floor button did not hide it');
    const withoutFloor = litPixels(decodePng(await page.locator('#view').screenshot()));
    await closePage(page);
    const off = await newPage({ width: 960, height: 540 });
    await off.goto(`${url}&floor=0`);
    check((await waitState(off, ['ready', 'error'])) === 'ready', 'not ready with floor=0');
    await twoFrames(off);
    check(!(await off.evaluate(() => window.reenactCamera().floor.visible)), 'floor=0 shows the floor');
    const linked = litPixels(decodePng(await off.locator('#view').screenshot()));
    await closePage(off);
    figures.floor_lit_px = { with: withFloor, without: withoutFloor, floor0: linked };
    log(`lit pixels: with the floor ${withFloor}, after its button ${withoutFloor}, with floor=0 ${linked}`);
    check(withFloor > withoutFloor + 2000, 'the floor grid draws (almost) nothing');
    check(Math.abs(linked - withoutFloor) <= 0.01 * withoutFloor, 'floor=0 and the button differ');
  });

  await test('orbit: a drag turns the view gently (degrees per pixel) and glides to a stop', async () => {
    const rows = [];
    for (const viewport of [{ width: 960, height: 540 }, { width: 1024, height: 768 }, { width: 390, height: 844 }]) {
      const page = await newPage(viewport);
      await page.goto(`${base()}/?reenactment=${bodyId}&t=1&paused=1&controls=0`);
      check((await waitState(page, ['ready', 'error'])) === 'ready', 'not ready');
      await twoFrames(page);
      const before = await page.evaluate(() => window.reenactCamera());
      const dx = Math.round(viewport.width / 4);
      const x0 = Math.round(viewport.width / 2 - dx / 2);
      const y0 = Math.round(viewport.height / 2);
      await page.mouse.move(x0, y0);
      await page.mouse.down();
      await page.mouse.move(x0 + dx, y0, { steps: 10 });
      await page.mouse.up();
      const released = await page.evaluate(() => window.reenactCamera());
      const after = await settledCamera(page);
      let turned = azimuthDeg(after) - azimuthDeg(before);
      turned = ((((turned + 180) % 360) + 360) % 360) - 180;
      const glide = Math.abs(azimuthDeg(after) - azimuthDeg(released));
      const perPx = Math.abs(turned) / dx;
      rows.push({ viewport: `${viewport.width}x${viewport.height}`, drag_px: dx, turned_deg: Number(turned.toFixed(2)), deg_per_px: Number(perPx.toFixed(4)), glide_deg: Number(glide.toFixed(2)), full_width_deg: Math.round(perPx * viewport.width) });
      check(Math.abs(perPx - after.orbit_deg_per_px) < 0.03, `${viewport.width}x${viewport.height}: turned ${perPx.toFixed(4)} deg/px, the page says ${after.orbit_deg_per_px}`);
      check(perPx >= 0.15 && perPx <= 0.45, `${viewport.width}x${viewport.height}: ${perPx.toFixed(4)} deg/px`);
      check(glide > 0.5, `${viewport.width}x${viewport.height}: no glide after the release (${glide.toFixed(2)} deg)`);
      await closePage(page);
    }
    figures.orbit = rows;
    log(`orbit: ${rows.map((r) => `${r.viewport} ${r.deg_per_px} deg/px (a ${r.drag_px} px drag turned ${r.turned_deg} deg, ${r.glide_deg} of it after the release; full width ${r.full_width_deg} deg)`).join('; ')}`);
  });

  await test('page frame rate at 1280x720', async () => {
    const page = await newPage({ width: 1280, height: 720 });
    await page.goto(`${base()}/?reenactment=${bodyId}&controls=0`);
    check((await waitState(page, ['playing', 'error'])) === 'playing', 'not playing');
    await sleep(2000);
    const fps = [];
    for (let i = 0; i < 4; ++i) {
      await sleep(1000);
      fps.push((await page.evaluate(() => window.reenactStats())).fps);
    }
    figures.page_fps_1280x720 = percentile(fps, 50);
    figures.page_fps_samples = fps;
    log(`page fps at 1280x720 (headless, software GL): ${fps.join(', ')}`);
    check(figures.page_fps_1280x720 > 0, 'no frames rendered');
    await closePage(page);
  });

  // ---- live
  await test('live preview: frames and latency', async () => {
    liveBrowser = liveBrowser || (await launchLiveBrowser());
    const page = await newPage({ width: 960, height: 540 }, liveBrowser);
    const live = await startLiveJob('live', 8);
    log(`live job ${live.jobId} on take ${live.takeId}`);
    await page.goto(`${base()}/?job=${live.jobId}`);
    const state = await waitState(page, ['playing', 'error'], 60);
    check(state === 'playing', `live state ${state}: ${await page.textContent('#error')}`);
    await page.waitForFunction(() => window.reenactLive().ended, null, { timeout: 120000 });
    const stats = await page.evaluate(() => window.reenactLive());
    liveJobId = live.jobId;
    await page.screenshot({ path: path.join(W, 'live.png') });
    const daemonExit = await live.daemon.exited;
    check(daemonExit.code === 0, `reenactd exited ${JSON.stringify(daemonExit)}`);
    const fitted = stats.last_frame_index - stats.first_frame_index + 1;
    const ratio = stats.frames_received / fitted;
    const p50 = percentile(stats.latencies_ms, 50);
    const p95 = percentile(stats.latencies_ms, 95);
    figures.live_page = '960x540, browser at nice 10';
    figures.live_frames_received = stats.frames_received;
    figures.live_frames_fitted_since_connect = fitted;
    figures.live_frames_ratio = Number(ratio.toFixed(4));
    figures.live_latency_p50_ms = p50;
    figures.live_latency_p95_ms = p95;
    figures.live_server_p50_ms = percentile(stats.server_ms, 50);
    figures.live_server_p95_ms = percentile(stats.server_ms, 95);
    figures.live_delivery_p50_ms = percentile(stats.delivery_ms, 50);
    figures.live_delivery_p95_ms = percentile(stats.delivery_ms, 95);
    figures.live_fit_ms_p50 = percentile(stats.fit_ms || [], 50);
    figures.live_end = stats.end;
    fs.writeFileSync(path.join(W, 'live-latencies.json'), JSON.stringify(stats));
    log(`live: ${stats.frames_received} of ${fitted} frames (${(100 * ratio).toFixed(1)} %), latency p50 ${p50} ms, p95 ${p95} ms; end ${JSON.stringify(stats.end)}`);
    check(stats.end && stats.end.type === 'end', `the follow did not end normally: ${JSON.stringify(stats.end)}`);
    // The server fits as many frames as its cores allow and skips the rest
    // (29 of an 8 s take once, on a 2-core machine that also compiled); the
    // ratio below is what the page is responsible for.
    check(stats.frames_received >= 15, `only ${stats.frames_received} frames`);
    check(ratio >= 0.9, `frames ratio ${ratio.toFixed(3)} < 0.9`);
    // The latency is measured, not asserted tightly: a test that times a
    // shared 2-core machine fails when the machine is busy (it read 173 ms
    // here once, 162 ms of it the server's fit). bench/live_e2e.cc measures
    // it; this bound only catches a preview that batches or stalls.
    check(p95 < 1000, `latency p95 ${p95} ms >= 1000: the preview stalls`);
    check(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
    await closePage(page);
  });

  await test('live preview reconnects after the WebSocket drops', async () => {
    liveBrowser = liveBrowser || (await launchLiveBrowser());
    const page = await newPage({ width: 960, height: 540 }, liveBrowser);
    let connections = 0;
    await page.routeWebSocket(/\/follow/, (ws) => {
      const n = ++connections;
      const upstream = ws.connectToServer();
      if (n !== 1) return;
      let frames = 0;
      upstream.onMessage((message) => {
        ws.send(message);
        if (typeof message === 'string' && message.includes('"type":"frame"') && ++frames === 8) {
          ws.close({ code: 4000, reason: 'dropped by the test' });
          upstream.close();
        }
      });
    });
    const live = await startLiveJob('drop', 7);
    await page.goto(`${base()}/?job=${live.jobId}`);
    check((await waitState(page, ['playing', 'error'], 60)) === 'playing', 'not playing');
    await page.waitForFunction(() => window.reenactLive().reconnects >= 1, null, { timeout: 30000 });
    const status = await page.textContent('#status');
    const before = (await page.evaluate(() => window.reenactLive())).frames_received;
    await page.waitForFunction(() => window.reenactLive().ended, null, { timeout: 120000 });
    const stats = await page.evaluate(() => window.reenactLive());
    await live.daemon.exited;
    log(`drop: ${connections} connections, ${stats.reconnects} reconnects, ${before} -> ${stats.frames_received} frames; status then: "${status}"`);
    check(connections >= 2, `${connections} connections`);
    check(stats.frames_received > before, 'no frames after the reconnect');
    check(stats.end && stats.end.type === 'end', `no end: ${JSON.stringify(stats.end)}`);
    await closePage(page);
  });

  // ---- structure and accessibility
  const livePageJob = async () => {
    if (liveJobId) return liveJobId;
    const live = await startLiveJob('landmarks', 3);
    await live.daemon.exited;
    liveJobId = live.jobId;
    return liveJobId;
  };

  await test('each page keeps its content in one <main>', async () => {
    const jobId = await livePageJob();
    for (const [what, url, inside] of [
      ['library', '/', ['#reenactments', '#live-list']],
      ['player', `/?reenactment=${bodyId}&paused=1`, ['#stage', '#hud', '#scrub']],
      ['live preview', `/?job=${jobId}`, ['#stage', '#hud', '#latency']],
    ]) {
      const page = await newPage({ width: 1024, height: 768 });
      await page.goto(`${base()}${url}`);
      await waitState(page, ['ready', 'playing', 'error']);
      const r = await page.evaluate((sel) => {
        const mains = document.querySelectorAll('main, [role="main"]');
        return { mains: mains.length, inside: sel.map((s) => !!(mains[0] && mains[0].querySelector(s))) };
      }, inside);
      log(`${what}: ${r.mains} main landmark(s); ${inside.map((s, i) => `${s} ${r.inside[i] ? 'in' : 'OUTSIDE'}`).join(', ')}`);
      check(r.mains === 1, `${what}: ${r.mains} main landmarks`);
      check(r.inside.every(Boolean), `${what}: content outside <main>`);
      await closePage(page);
    }
  });

  await test('accessibility: axe-core finds nothing serious or critical (library, player, live preview; tablet and phone)', async () => {
    try {
      requireWeb.resolve('axe-core/axe.min.js');
    } catch (e) {
      throw new Error(`axe-core is missing (cd clients/web && npm ci): ${e.message}`);
    }
    const jobId = await livePageJob();
    const counts = {};
    const bad = [];
    for (const [size, viewport] of [['tablet', { width: 1024, height: 768 }], ['phone', { width: 390, height: 844 }]]) {
      for (const [what, url, ready] of [
        ['library', '/', async (page) => page.waitForFunction(() => document.querySelectorAll('.still img').length >= 2, null, { timeout: 60000 })],
        ['player', `/?reenactment=${bodyId}&paused=1&t=1`, null],
        ['live', `/?job=${jobId}`, null],
      ]) {
        const page = await newPage(viewport);
        await page.goto(`${base()}${url}`);
        await waitState(page, ['ready', 'playing', 'error']);
        if (ready) await ready(page);
        await twoFrames(page);
        const violations = await axeViolations(page);
        const tally = { critical: 0, serious: 0, moderate: 0, minor: 0 };
        for (const v of violations) tally[v.impact] = (tally[v.impact] || 0) + v.nodes;
        counts[`${what}_${size}`] = tally;
        log(`axe ${what} ${size} ${viewport.width}x${viewport.height}: ${JSON.stringify(tally)}` +
          (violations.length ? ` ${violations.map((v) => `${v.impact} ${v.id} x${v.nodes} (${v.targets.join(' | ')})`).join('; ')}` : ''));
        for (const v of violations) if (v.impact === 'serious' || v.impact === 'critical') bad.push(`${what} ${size}: ${v.impact} ${v.id} (${v.help}) at ${v.targets.join(' | ')}`);
        await closePage(page);
      }
    }
    figures.axe = counts;
    check(bad.length === 0, `axe: ${bad.join('; ')}`);
  });

  // ---- bad input
  await test('unknown reenactment: error state with a message', async () => {
    const page = await newPage();
    await page.goto(`${base()}/?reenactment=r-20000101-000000-dead`);
    check((await waitState(page, ['error', 'ready', 'playing'])) === 'error', 'no error state');
    const text = await page.textContent('#error-message');
    check(text && text.length > 5, `message "${text}"`);
    log(`unknown id says: ${text}`);
    await closePage(page);
  });

  for (const [what, cut] of [
    ['truncated', (b) => b.subarray(0, Math.floor(b.length / 2))],
    ['not-a-glb', () => Buffer.from('this is not a glTF file at all')],
  ]) {
    await test(`${what} model.glb: error state with a message`, async () => {
      const page = await newPage();
      await page.route('**/model.glb', async (route) => {
        const response = await route.fetch();
        const body = cut(await response.body());
        const headers = { ...response.headers() };
        delete headers['content-length'];
        delete headers.etag;
        await route.fulfill({ status: 200, headers, body });
      });
      await page.goto(`${base()}/?reenactment=${bodyId}`);
      check((await waitState(page, ['error', 'ready', 'playing'])) === 'error', 'no error state');
      const text = await page.textContent('#error-message');
      check(text && text.length > 5, `message "${text}"`);
      check(await page.isVisible('#error button'), 'no retry button');
      log(`${what} glb says: ${text}`);
      await closePage(page);
    });
  }

  await test('server gone: the library says so and recovers', async () => {
    const page = await newPage();
    await page.goto(`${base()}/`);
    check((await waitState(page, ['ready', 'error'])) === 'ready', 'library not ready');
    const { grpc, http } = server;
    await stop(server.child);
    const t0 = Date.now();
    await waitState(page, 'error', 30);
    const text = await page.textContent('#error-message');
    log(`server gone after ${Date.now() - t0} ms: "${text}"`);
    await startServer(grpc, http);
    const t1 = Date.now();
    await waitState(page, 'ready', 30);
    log(`library back ${Date.now() - t1} ms after the server`);
    const ids = await page.$$eval('.card[data-id]', (els) => els.map((e) => e.dataset.id));
    check(ids.includes(bodyId) && ids.includes(rigidId), 'cards after recovery');
    check(await page.isHidden('#error'), 'the error is still shown');
    await closePage(page);
  });

  // ---- tokens
  await test('tokens: prompt on 401 in a browser user\'s words, #token= kept, role refused on 403, WebSocket with access_token', async () => {
    const tokens = path.join(W, 'tokens.json');
    fs.rmSync(tokens, { force: true });
    const token = {};
    for (const role of ['viewer', 'capture']) {
      token[role] = (await reenact(['auth', 'add', '--file', tokens, '--role', role, '--name', `web-test-${role}`], { name: `auth-${role}` })).out.trim();
    }
    const { grpc, http } = server;
    await stop(server.child);
    await startServer(grpc, http, ['--auth', tokens]);

    // No token: the library asks for one.
    let page = await newPage();
    await page.goto(`${base()}/`);
    check((await waitState(page, ['error', 'ready'])) === 'error', 'no error without a token');
    check(await page.isVisible('#token-input'), 'no token prompt');
    const asked = await page.innerText('#error');
    log(`no token: "${asked.replace(/\s+/g, ' ')}"`);
    // A coach's words: what a token is and who has one, not the command
    // line's flags.
    check(!/--token-file|REENACT_TOKEN|--[a-z]/.test(asked), `the prompt speaks command line: "${asked}"`);
    check(/access token/i.test(asked) && /whoever runs the Reenact server/.test(asked), `the prompt does not say what a token is or who has one: "${asked}"`);
    check((await page.getByLabel('Access token').count()) === 1, 'the token field has no label');
    // Typing the token in the prompt.
    await page.fill('#token-input', token.viewer);
    await Promise.all([page.waitForNavigation(), page.click('.token-form button')]);
    check((await waitState(page, ['error', 'ready'])) === 'ready', `with the typed token: ${await page.textContent('#error')}`);
    await closePage(page);

    // A token in the fragment: kept, and gone from the address bar.
    page = await newPage();
    await page.goto(`${base()}/#token=${token.viewer}`);
    check((await waitState(page, ['error', 'ready'])) === 'ready', `with #token: ${await page.textContent('#error')}`);
    check(!page.url().includes(token.viewer), `the token stays in the address bar: ${page.url()}`);
    check((await page.evaluate(() => localStorage.getItem('reenact.token'))) === token.viewer, 'token not kept');
    const ids = await page.$$eval('.card[data-id]', (els) => els.map((e) => e.dataset.id));
    check(ids.includes(bodyId), 'no cards with the token');
    await page.goto(`${base()}/?reenactment=${bodyId}`);
    check((await waitState(page, ['playing', 'error'])) === 'playing', `player with the token: ${await page.textContent('#error')}`);
    if (liveJobId) {
      // The live job's follow ended long ago: the WebSocket (with
      // ?access_token=) says so at once.
      await page.goto(`${base()}/?job=${liveJobId}`);
      await page.waitForFunction(() => window.reenactLive().ended, null, { timeout: 30000 });
      const end = (await page.evaluate(() => window.reenactLive())).end;
      log(`follow of a finished live job with a token: ${JSON.stringify(end)}`);
      check(end && (end.type === 'end' || (end.type === 'error' && end.code !== 'UNAUTHENTICATED')), `follow: ${JSON.stringify(end)}`);
    }
    await closePage(page);

    // A role that may not read: 403.
    page = await newPage();
    await page.goto(`${base()}/#token=${token.capture}`);
    check((await waitState(page, ['error', 'ready'])) === 'error', 'a capture token may list reenactments?');
    const text = await page.textContent('#error-message');
    log(`capture token: "${text}"`);
    check(/role/.test(text), `403 message: ${text}`);
    await closePage(page);

    // A token the server does not know: the prompt again, saying so.
    page = await newPage();
    await page.goto(`${base()}/#token=rnt_not-a-token-of-this-server`);
    check((await waitState(page, ['error', 'ready'])) === 'error', 'an unknown token is let in?');
    const refused = await page.textContent('#error-message');
    log(`unknown token: "${refused}"`);
    check(await page.isVisible('#token-input'), 'no token prompt for an unknown token');
    check(/not one the server knows/.test(refused) && /whoever runs the Reenact server/.test(refused) && !/--[a-z]/.test(refused), `unknown token message: ${refused}`);
    await closePage(page);
  });
}

let exitCode = 0;
try {
  await main();
} catch (e) {
  log(`ERROR ${e.stack || e.message}`);
  exitCode = 1;
} finally {
  if (browser) await browser.close().catch(() => {});
  if (liveBrowser) await liveBrowser.close().catch(() => {});
  for (const child of [...children]) await stop(child);
}
const failed = results.filter((r) => !r.ok);
log(`${results.length - failed.length} passed, ${failed.length} failed${failed.length ? `: ${failed.map((f) => f.name).join('; ')}` : ''}`);
if (failed.length) exitCode = 1;
console.log(JSON.stringify({ figures, passed: results.length - failed.length, failed: failed.length, work: W }));
if (!args.keep && !args.work && exitCode === 0) fs.rmSync(W, { recursive: true, force: true });
process.exit(exitCode);
