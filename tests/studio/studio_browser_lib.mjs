// What the studio's browser test and its frame-rate benchmark share: playwright-core from
// web/node_modules, Debian's chromium headless (WebGL through SwiftShader where there is no GPU),
// and a `flockmorph studio` started on a free port.
import { spawn } from 'node:child_process';
import { createRequire } from 'node:module';
import { join } from 'node:path';

export const CHROMIUM = '/usr/bin/chromium';

// playwright-core as web/package-lock.json pins it, or null where `npm ci` has not run.
export function playwright(source) {
  try { return createRequire(join(source, 'web', 'package.json'))('playwright-core'); } catch { return null; }
}

// Never a browser Playwright downloads: Debian's, with the flags that give it WebGL without a GPU.
export function launchChromium(pw) {
  return pw.chromium.launch({ executablePath: CHROMIUM,
    args: ['--headless=new', '--no-sandbox', '--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'] });
}

// `flockmorph studio TARGET --port 0`, and the address it prints.
export function startStudio(cli, target) {
  const proc = spawn(cli, ['studio', target, '--port', '0', '--no-browser'], { stdio: ['ignore', 'pipe', 'pipe'] });
  proc.stderr.on('data', (d) => process.stderr.write(`studio: ${d}`));
  return new Promise((resolve, reject) => {
    let out = '';
    proc.stdout.on('data', (d) => { out += d; const m = /open (\S+)/.exec(out); if (m) resolve({ proc, url: m[1] }); });
    proc.on('exit', (code) => reject(new Error(`studio exited with ${code}: ${out}`)));
  });
}

export function stopStudio(s) {
  return new Promise((resolve) => { s.proc.removeAllListeners('exit'); s.proc.on('exit', resolve); s.proc.kill('SIGTERM'); });
}

