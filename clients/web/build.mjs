// Builds Reenact's browser client into one folder the server serves:
// index.html, app.js (one minified bundle, three.js included) and app.css.
//
//   node clients/web/build.mjs [--outdir DIR] [--sourcemap]
//
// DIR defaults to clients/web/dist. Prints the bundle's size, raw and
// gzipped; exits non-zero on failure.

import { copyFile, mkdir, readFile, stat } from 'node:fs/promises';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { gzipSync } from 'node:zlib';

const here = path.dirname(fileURLToPath(import.meta.url));
const GZIP_BUDGET_BYTES = 1024 * 1024;

function parseArgs(argv) {
  const args = { outdir: path.join(here, 'dist'), sourcemap: false };
  for (let i = 0; i < argv.length; ++i) {
    const a = argv[i];
    if (a === '--outdir' && i + 1 < argv.length) args.outdir = path.resolve(argv[++i]);
    else if (a.startsWith('--outdir=')) args.outdir = path.resolve(a.slice('--outdir='.length));
    else if (a === '--sourcemap') args.sourcemap = true;
    else if (a === '--help' || a === '-h') {
      console.log('usage: node build.mjs [--outdir DIR] [--sourcemap]');
      process.exit(0);
    } else {
      throw new Error(`unknown argument ${a}`);
    }
  }
  return args;
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  let esbuild;
  try {
    esbuild = await import('esbuild');
  } catch (e) {
    throw new Error(`esbuild is missing; run 'npm ci' in ${here} (${e.message})`);
  }
  await mkdir(args.outdir, { recursive: true });
  const result = await esbuild.build({
    absWorkingDir: here,
    entryPoints: [
      { in: path.join(here, 'src/main.js'), out: 'app' },
      { in: path.join(here, 'src/app.css'), out: 'app' },
    ],
    bundle: true,
    minify: true,
    format: 'esm',
    target: ['es2020', 'chrome90', 'safari15', 'firefox90'],
    outdir: args.outdir,
    sourcemap: args.sourcemap,
    legalComments: 'eof',
    logLevel: 'warning',
    metafile: true,
    define: { 'process.env.NODE_ENV': '"production"' },
  });
  if (result.errors.length) throw new Error('the bundle failed');
  await copyFile(path.join(here, 'src/index.html'), path.join(args.outdir, 'index.html'));

  const report = {};
  for (const name of ['app.js', 'app.css', 'index.html']) {
    const bytes = await readFile(path.join(args.outdir, name));
    report[name] = { raw: bytes.length, gzip: gzipSync(bytes, { level: 9 }).length };
  }
  const total = Object.values(report).reduce((s, r) => s + r.gzip, 0);
  for (const [name, r] of Object.entries(report)) {
    console.log(`${name.padEnd(11)} ${String(r.raw).padStart(9)} bytes, ${String(r.gzip).padStart(8)} gzipped`);
  }
  console.log(
    `bundle      ${(total / 1024).toFixed(1)} KiB gzipped in all (budget ${GZIP_BUDGET_BYTES / 1024} KiB) -> ${args.outdir}`,
  );
  if (total > GZIP_BUDGET_BYTES)
    throw new Error(`the bundle is ${total} bytes gzipped, over the ${GZIP_BUDGET_BYTES} budget`);
  await stat(path.join(args.outdir, 'index.html'));
}

main().catch((e) => {
  console.error(`build.mjs: ${e.message || e}`);
  process.exit(1);
});
