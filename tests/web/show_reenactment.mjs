// Opens one reenactment in the tablet app, as a coach's tablet would, in
// headless Chromium (playwright-core from clients/web's packages) and says
// what it showed: the player's state, its frame count, the time from the
// page's start to its first drawn frame, and how much of the stage the body
// covers (pixels that differ from the background, floor grid off). Prints
// one JSON object; exits 0 when it played, 1 otherwise, 77 (skipped) without
// the packages or the browser.
//
//   node tests/web/show_reenactment.mjs --url http://127.0.0.1:PORT --reenactment ID
//       [--token TOKEN] [--chromium /usr/bin/chromium] [--screenshot FILE.png]
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const requireWeb = createRequire(path.resolve(here, '../../clients/web/package.json'));

function parseArgs(argv) {
  const args = { url: '', reenactment: '', token: '', chromium: '/usr/bin/chromium', screenshot: '' };
  for (let i = 0; i < argv.length; ++i) {
    const key = argv[i].replace(/^--/, '');
    if (!(key in args) || i + 1 >= argv.length) throw new Error(`bad argument ${argv[i]}`);
    args[key] = argv[++i];
  }
  if (!args.url || !args.reenactment) throw new Error('--url and --reenactment are needed');
  return args;
}

// The share of pixels whose colour differs from the top-left corner's (the
// background) by more than `threshold` in some channel.
function coveredFraction(png, threshold = 24) {
  const d = png.data;
  let covered = 0;
  for (let i = 0; i < d.length; i += 4) {
    if (Math.abs(d[i] - d[0]) > threshold || Math.abs(d[i + 1] - d[1]) > threshold || Math.abs(d[i + 2] - d[2]) > threshold) {
      ++covered;
    }
  }
  return covered / (png.width * png.height);
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  let chromium;
  let PNG;
  try {
    ({ chromium } = requireWeb('playwright-core'));
    ({ PNG } = requireWeb('pngjs'));
  } catch (e) {
    console.error(`show_reenactment: SKIPPED: the packages of clients/web are missing (npm ci --prefix clients/web): ${e.message}`);
    process.exit(77);
  }
  if (!fs.existsSync(args.chromium)) {
    console.error(`show_reenactment: SKIPPED: no browser at ${args.chromium}`);
    process.exit(77);
  }
  const browser = await chromium.launch({
    executablePath: args.chromium,
    args: ['--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
  });
  const result = { state: '', frames: 0, first_frame_ms: -1, covered: 0, errors: [] };
  try {
    // A tablet held in landscape.
    const context = await browser.newContext({ viewport: { width: 1180, height: 820 }, deviceScaleFactor: 1 });
    await context.addInitScript(() => {
      window.__firstFrameMs = -1;
      const watch = () => {
        const state = document.body && document.body.dataset.state;
        if (window.__firstFrameMs < 0 && (state === 'ready' || state === 'playing')) window.__firstFrameMs = performance.now();
      };
      document.addEventListener('DOMContentLoaded', () => {
        watch();
        new MutationObserver(watch).observe(document.body, { attributes: true, attributeFilter: ['data-state'] });
      });
    });
    const page = await context.newPage();
    page.on('pageerror', (e) => result.errors.push(e.message));
    const token = args.token ? `#token=${encodeURIComponent(args.token)}` : '';
    await page.goto(`${args.url}/?reenactment=${encodeURIComponent(args.reenactment)}&floor=0&paused=1&t=0${token}`);
    await page.waitForFunction(() => ['ready', 'playing', 'paused', 'error'].includes(document.body.dataset.state), null, {
      timeout: 120000,
    });
    result.state = await page.evaluate(() => document.body.dataset.state);
    if (result.state === 'error') {
      result.errors.push(await page.textContent('#error'));
    } else {
      // Two animation frames, so that the paused frame is on the canvas.
      await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
      result.frames = (await page.evaluate(() => window.reenactStats())).frames;
      result.first_frame_ms = Math.round(await page.evaluate(() => window.__firstFrameMs));
      const shot = await page.locator('#stage canvas').first().screenshot();
      if (args.screenshot) fs.writeFileSync(args.screenshot, shot);
      result.covered = Number(coveredFraction(PNG.sync.read(shot)).toFixed(4));
    }
  } finally {
    await browser.close();
  }
  console.log(JSON.stringify(result));
  process.exit(result.state !== 'error' && result.frames > 0 && result.errors.length === 0 ? 0 : 1);
}

main().catch((e) => {
  console.error(`show_reenactment: ${e.stack || e}`);
  process.exit(1);
});
