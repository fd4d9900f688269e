// Builds the studio's page (docs/studio.md) into --outdir: index.html, app.js (three.js, lil-gui
// and src/ bundled by esbuild, no network needed) and app.css. Run by CMake (cmake/studio.cmake).
import { build } from 'esbuild';
import { copyFileSync, mkdirSync, renameSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const at = process.argv.indexOf('--outdir');
const outdir = at > 0 ? process.argv[at + 1] : join(here, 'dist');
mkdirSync(outdir, { recursive: true });
// Written as .partial and renamed, so a page is never half-built (CMake's output is index.html).
await build({
  entryPoints: [join(here, 'src', 'main.js')],
  bundle: true,
  format: 'esm',
  target: 'es2020',
  minify: true,
  sourcemap: false,
  legalComments: 'eof',
  outfile: join(outdir, 'app.js.partial'),
  logLevel: 'warning',
});
renameSync(join(outdir, 'app.js.partial'), join(outdir, 'app.js'));
copyFileSync(join(here, 'src', 'app.css'), join(outdir, 'app.css'));
copyFileSync(join(here, 'index.html'), join(outdir, 'index.html'));
