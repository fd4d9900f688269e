// The studio page's frame rate on a scene, by the page's own counter (frames of the flock shown per
// second): a benchmark figure for docs/studio.md, not a test.
//   node tests/studio/bench_studio_fps.mjs --cli BUILD/flockmorph --source REPO [--seconds S]
//        [--variants before,after] [--rounds R] SCENE
// Prints JSON: the run (frames, agents, seconds until the live run finished) and, for each variant
// of the drawing (VARIANTS below), the frame rate playing at the scene's rate and as fast as frames
// come, and the mean resolution ratio while it played, in headless chromium (SwiftShader: the CPU
// draws, so a machine with a GPU and a desktop browser does better). The variants are measured in
// turn, R rounds, on the same frames (in one page, or one a page query), so that the machine's load falls on each
// alike; each figure is the median of its rounds. cpu_ms_per_frame is the browser's processor time
// (every chromium process, user and system, from /proc) per frame shown: on a machine shared with
// other jobs the frame rate follows the processor time the browser gets, this does much less.
import { readdirSync, readFileSync } from 'node:fs';
import { launchChromium, playwright, startStudio, stopStudio } from './studio_browser_lib.mjs';

const arg = (name, fallback) => { const i = process.argv.indexOf(name); return i > 0 ? process.argv[i + 1] : fallback; };
const cli = arg('--cli'), source = arg('--source'), seconds = Number(arg('--seconds', 6));
const rounds = Number(arg('--rounds', 2)), chosen = arg('--variants', 'before,after').split(',');
const scene = process.argv[process.argv.length - 1];

// before: the studio's first drawing (lit on both sides, always full resolution); after: today's.
// The others take one lever at a time; page: the page as it is (another build's page, too). Each
// query (none today) is a page of its own.
const VARIANTS = {
  page: { query: '' },
  before: { tetStyle: { material: 'lambert', cull: false, wide: true }, pointStyle: 'sprite', dynamic: false, query: '' },
  cull: { tetStyle: { material: 'lambert', cull: true, wide: true }, dynamic: false, query: '' },
  flat: { tetStyle: { material: 'flat', cull: true, tiny: 3, rest: true }, dynamic: false, query: '' },
  dynamic: { tetStyle: { material: 'flat', cull: true }, dynamic: true, query: '' },
  after: { tetStyle: { material: 'flat', cull: true, tiny: 3, rest: true }, pointStyle: 'disc', dynamic: true, query: '' },
  // the points as three.js's textured sprites (the page before the disc shader), the rest as 'after'
  sprite: { tetStyle: { material: 'flat', cull: true, tiny: 3, rest: true }, pointStyle: 'sprite', dynamic: true, query: '' },
  // the page before the shapes at rest were drawn as their surface and 16-bit indices: 'after' as it was
  plain: { tetStyle: { material: 'flat', cull: true, tiny: 3, wide: true }, dynamic: true, query: '' },
};

// Processor seconds (user + system) of this process's descendants but `except`'s (the studio).
function browserCpu(except) {
  const procs = new Map();
  for (const d of readdirSync('/proc')) {
    if (!/^\d+$/.test(d)) continue;
    try {
      const s = readFileSync(`/proc/${d}/stat`, 'utf8'), f = s.slice(s.lastIndexOf(')') + 2).split(' ');
      procs.set(Number(d), { ppid: Number(f[1]), cpu: (Number(f[11]) + Number(f[12])) / 100 });
    } catch { /* gone */ }
  }
  let total = 0;
  const todo = [...procs].filter(([, p]) => p.ppid === process.pid).map(([pid]) => pid);
  while (todo.length) {
    const pid = todo.pop();
    if (pid === except) continue;
    total += procs.get(pid).cpu;
    for (const [c, p] of procs) if (p.ppid === pid) todo.push(c);
  }
  return total;
}

async function rate(page, fastest, studioPid) {
  await page.evaluate((f) => { const s = window.studio; s.fastest = f; s.follow = false; s.seek(0); s.playing = true; }, fastest);
  await page.waitForTimeout(1500); // one counter period in
  const samples = [], ratios = [];
  const cpu0 = browserCpu(studioPid), shown0 = await page.evaluate(() => window.studio.shownCount);
  for (let t = 0; t < seconds; t++) {
    await page.waitForTimeout(1000);
    samples.push(await page.evaluate(() => window.studio.counter.fps));
    ratios.push(await page.evaluate(() => window.studio.view.resolution?.ratio ?? 1));
    await page.evaluate(() => { const s = window.studio; if (s.current >= s.status.frames - 2) s.seek(0); });
  }
  const mean = (a) => a.reduce((x, y) => x + y, 0) / a.length;
  const counted = (await page.evaluate(() => window.studio.shownCount)) - shown0;
  const shown = Number.isFinite(counted) ? counted : mean(samples) * seconds; // a page without the count
  return { fps: mean(samples), ratio: mean(ratios), cpu: ((browserCpu(studioPid) - cpu0) * 1000) / Math.max(1, shown) };
}

const median = (a) => { const s = [...a].sort((x, y) => x - y); return s.length % 2 ? s[(s.length - 1) / 2] : (s[s.length / 2 - 1] + s[s.length / 2]) / 2; };
const round1 = (x) => Math.round(x * 10) / 10;

// A page of the studio at url, with every frame of the finished live run in it.
async function openPage(browser, url) {
  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  await page.goto(url);
  await page.waitForFunction(() => window.studio.status.stage === 'finished', null, { timeout: 300000 });
  const frames = await page.evaluate(() => window.studio.status.frames);
  await page.evaluate((n) => { for (let k = 0; k < n; k++) window.studio.ask(k); }, frames);
  await page.waitForFunction((n) => window.studio.frames.size >= n, frames, { timeout: 120000 });
  await page.evaluate(() => { window.studio.playing = false; }); // still while the others are measured
  return page;
}

const browser = await launchChromium(playwright(source));
const studio = await startStudio(cli, scene);
try {
  const t0 = Date.now(), pages = {};
  for (const name of chosen) {
    const v = VARIANTS[name];
    if (v === undefined) throw new Error(`no variant '${name}' (${Object.keys(VARIANTS).join(', ')})`);
    pages[v.query] ??= await openPage(browser, studio.url + v.query);
  }
  const live = (Date.now() - t0) / 1000;
  const status = await Object.values(pages)[0].evaluate(() => window.studio.status);
  const measured = Object.fromEntries(chosen.map((v) => [v, { scene_rate: [], fastest: [], ratio: [], cpu: [] }]));
  for (let r = 0; r < rounds; r++) {
    for (const name of chosen) {
      const v = VARIANTS[name], page = pages[v.query];
      await page.bringToFront();
      if (v.tetStyle) {
        await page.evaluate((x) => {
          const view = window.studio.view;
          view.setTetStyle(x.tetStyle);
          if (x.pointStyle && view.setPointStyle) view.setPointStyle(x.pointStyle);
          view.dynamicResolution = x.dynamic;
        }, v);
      }
      const a = await rate(page, false, studio.proc.pid), b = await rate(page, true, studio.proc.pid);
      await page.evaluate(() => { window.studio.playing = false; });
      measured[name].scene_rate.push(a.fps), measured[name].fastest.push(b.fps), measured[name].ratio.push((a.ratio + b.ratio) / 2);
      measured[name].cpu.push(b.cpu);
      console.error(`round ${r} ${name}: ${a.fps.toFixed(1)} fps at the scene's rate, ${b.fps.toFixed(1)} as fast as frames come (${b.cpu.toFixed(0)} ms of processor a frame), ratio ${a.ratio.toFixed(2)} / ${b.ratio.toFixed(2)}`);
    }
  }
  const variants = Object.fromEntries(Object.entries(measured).map(([k, m]) => [k, {
    fps_scene_rate: round1(median(m.scene_rate)), fps_fastest: round1(median(m.fastest)),
    cpu_ms_per_frame: Math.round(median(m.cpu)), mean_resolution_ratio: Math.round(median(m.ratio) * 100) / 100,
    rounds: m.scene_rate.map(round1) }]));
  console.log(JSON.stringify({ scene, agents: status.agents, kind: status.kind, frames: status.frames,
    pages_opened_to_live_run_finished_seconds: live, frame_rate: status.frame_rate, variants }));
} finally {
  await stopStudio(studio);
  await browser.close();
}
