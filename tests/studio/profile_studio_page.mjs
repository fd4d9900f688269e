// Where the studio page's main thread spends a played frame: a benchmark aid for docs/studio.md
// ("Frame rate"), not a test. Plays the finished live run as fast as frames come and records
// chromium's JavaScript profile (CDP Profiler) for S seconds; prints JSON: frames shown, the main
// thread's milliseconds a frame by function (self time, the top ones) and by the page's own stages
// (timed in the page: the frame's arrays written, the faces chosen, three.js's draw call).
//   node tests/studio/profile_studio_page.mjs --cli BUILD/flockmorph --source REPO [--seconds S] SCENE
import { launchChromium, playwright, startStudio, stopStudio } from './studio_browser_lib.mjs';

const arg = (name, fallback) => { const i = process.argv.indexOf(name); return i > 0 ? process.argv[i + 1] : fallback; };
const cli = arg('--cli'), source = arg('--source'), seconds = Number(arg('--seconds', 5));
const scene = process.argv[process.argv.length - 1];

// Wraps the view's stages with timers (page side).
function instrument() {
  const v = window.studio.view, t = (window.stageMs = { showFrame: 0, cullFaces: 0, render: 0, resize: 0 });
  window.stageCalls = { showFrame: 0, cullFaces: 0, render: 0, resize: 0 };
  for (const name of Object.keys(t)) {
    const f = v[name].bind(v);
    v[name] = (...a) => {
      const t0 = performance.now(); const r = f(...a); t[name] += performance.now() - t0; window.stageCalls[name]++;
      return r;
    };
  }
}

const browser = await launchChromium(playwright(source));
const studio = await startStudio(cli, scene);
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  await page.goto(studio.url);
  await page.waitForFunction(() => window.studio.status.stage === 'finished', null, { timeout: 300000 });
  const frames = await page.evaluate(() => window.studio.status.frames);
  await page.evaluate((n) => { for (let k = 0; k < n; k++) window.studio.ask(k); }, frames);
  await page.waitForFunction((n) => window.studio.frames.size >= n, frames, { timeout: 120000 });
  await page.evaluate(instrument);
  await page.evaluate(() => { const s = window.studio; s.fastest = true; s.follow = false; s.seek(0); s.playing = true; });
  await page.waitForTimeout(1000);
  const cdp = await page.context().newCDPSession(page);
  await cdp.send('Profiler.enable');
  await cdp.send('Profiler.setSamplingInterval', { interval: 200 });
  const shown0 = await page.evaluate(() => {
    for (const k in window.stageMs) window.stageMs[k] = window.stageCalls[k] = 0;
    return window.studio.shownCount;
  });
  await cdp.send('Profiler.start');
  for (let t = 0; t < seconds; t++) {
    await page.waitForTimeout(1000);
    await page.evaluate(() => { const s = window.studio; if (s.current >= s.status.frames - 2) s.seek(0); });
  }
  const { profile } = await cdp.send('Profiler.stop');
  const shown = (await page.evaluate(() => window.studio.shownCount)) - shown0;
  const stages = await page.evaluate(() => window.stageMs), calls = await page.evaluate(() => window.stageCalls);
  const self = new Map(), byId = new Map(profile.nodes.map((n) => [n.id, n]));
  const dt = profile.timeDeltas, total = profile.endTime - profile.startTime;
  profile.samples.forEach((id, i) => {
    const n = byId.get(id).callFrame, key = `${n.functionName || '(anonymous)'} ${n.url.split('/').pop()}:${n.lineNumber}`;
    self.set(key, (self.get(key) ?? 0) + (dt[i + 1] ?? 0) / 1000);
  });
  const perFrame = (ms) => Math.round((ms / Math.max(1, shown)) * 100) / 100;
  const top = [...self].sort((a, b) => b[1] - a[1]).slice(0, 15).map(([k, ms]) => [k, perFrame(ms)]);
  console.log(JSON.stringify({ scene, frames_shown: shown, seconds: total / 1e6,
    fps: Math.round((shown / (total / 1e6)) * 10) / 10,
    stage_ms_per_frame: Object.fromEntries(Object.entries(stages).map(([k, ms]) => [k, perFrame(ms)])), stage_calls: calls,
    self_ms_per_frame: top }));
  await page.close();
} finally {
  await stopStudio(studio);
  await browser.close();
}
