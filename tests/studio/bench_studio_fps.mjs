// The studio page's frame rate on a scene, by the page's own counter (frames of the flock shown per
// second): a benchmark figure for docs/studio.md, not a test.
//   node tests/studio/bench_studio_fps.mjs --cli BUILD/flockmorph --source REPO SCENE [--seconds S]
// Prints JSON: the run (frames, agents, seconds until the live run finished) and the frame rate
// playing at the scene's rate and as fast as frames come, in headless chromium (SwiftShader: the
// CPU draws, so a machine with a GPU and a desktop browser does better).
import { launchChromium, playwright, startStudio, stopStudio } from './studio_browser_lib.mjs';

const arg = (name, fallback) => { const i = process.argv.indexOf(name); return i > 0 ? process.argv[i + 1] : fallback; };
const cli = arg('--cli'), source = arg('--source'), seconds = Number(arg('--seconds', 6));
const scene = process.argv[process.argv.length - 1];

async function rate(page, fastest) {
  await page.evaluate((f) => { const s = window.studio; s.fastest = f; s.follow = false; s.seek(0); s.playing = true; }, fastest);
  await page.waitForTimeout(1500); // one counter period in
  const samples = [];
  for (let t = 0; t < seconds; t++) {
    await page.waitForTimeout(1000);
    samples.push(await page.evaluate(() => window.studio.counter.fps));
    await page.evaluate(() => { const s = window.studio; if (s.current >= s.status.frames - 2) s.seek(0); });
  }
  return Math.round((samples.reduce((a, b) => a + b, 0) / samples.length) * 10) / 10;
}

const browser = await launchChromium(playwright(source));
const studio = await startStudio(cli, scene);
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  const t0 = Date.now();
  await page.goto(studio.url);
  await page.waitForFunction(() => window.studio.status.stage === 'finished', null, { timeout: 300000 });
  const live = (Date.now() - t0) / 1000;
  const status = await page.evaluate(() => window.studio.status);
  await page.evaluate((n) => { for (let k = 0; k < n; k++) window.studio.ask(k); }, status.frames);
  await page.waitForFunction((n) => window.studio.frames.size >= n, status.frames, { timeout: 120000 });
  const sceneRate = await rate(page, false), fastest = await rate(page, true);
  console.log(JSON.stringify({ scene, agents: status.agents, kind: status.kind, frames: status.frames,
    live_run_seconds: live, fps_scene_rate: sceneRate, fps_fastest: fastest, frame_rate: status.frame_rate }));
} finally {
  await stopStudio(studio);
  await browser.close();
}
