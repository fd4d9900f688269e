// test_studio_browser: the studio's page in a real browser (Debian's chromium, headless, driven by
// playwright-core from web/node_modules), against a running `flockmorph studio`:
//   the canvas shows the flock; a control point dragged with real mouse events moves the route;
//   a panel slider dragged with the mouse and a sketched path (which the route then follows)
//   re-run the scene; Save writes the scene, and `flockmorph run` of it writes byte for byte the
//   frames the page received (SHA-256 of each frame's tet vertices, from the Python reader); a
//   played cache's frame K is the reader's; a wrong token and a foreign Origin are refused. In a
//   shot, a group picked in the panel shows its own path point between its shapes, and its slider
//   edits the group's key; `flockmorph run` of the saved shot gives the page's frames again; an
//   edit of the groups list itself makes the panel's "Edit" list and the handles follow. A point
//   flock's cache plays with its dots where the agents are, as large as three.js's sprites drew them.
// Exit 77 (ctest SKIP) only when chromium, node's playwright-core or the built page is missing,
// or with --skip (the sanitizer build).
//   node test_studio_browser.mjs --cli FLOCKMORPH --source REPO --tmp DIR [--python PY] [--shots DIR] [--skip WHY]
import { spawnSync } from 'node:child_process';
import { copyFileSync, existsSync, mkdirSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { CHROMIUM, launchChromium, playwright, startStudio, stopStudio } from './studio_browser_lib.mjs';

const arg = (name, fallback) => { const i = process.argv.indexOf(name); return i > 0 ? process.argv[i + 1] : fallback; };
const cli = arg('--cli'), source = arg('--source'), tmp = join(arg('--tmp'), 'studio_browser');
const python = arg('--python', '/usr/bin/python3'), shots = arg('--shots', tmp);
const t0 = Date.now();
const log = (...a) => console.log(`[${((Date.now() - t0) / 1000).toFixed(1)} s]`, ...a);
const fail = (msg) => { console.error(`test_studio_browser: FAIL: ${msg}`); process.exitCode = 1; throw new Error(msg); };
const check = (ok, msg) => { if (!ok) fail(msg); };

function skip(why) { console.log(`test_studio_browser: SKIPPED: ${why}`); process.exit(77); }

function cacheFacts(cache, ...extra) {
  const r = spawnSync(python, [join(source, 'tests', 'studio', 'cache_facts.py'), cache, ...extra], { encoding: 'utf8' });
  check(r.status === 0, `cache_facts.py ${cache}: ${r.stderr}`);
  return JSON.parse(r.stdout);
}

// The page's state, once the run of a newer generation than `after` has finished.
async function finishedRun(page, after = 0) {
  await page.waitForFunction((g) => window.studio.status.generation > g && window.studio.status.stage === 'finished',
    after, { timeout: 60000 });
  return page.evaluate(() => ({ generation: window.studio.status.generation, frames: window.studio.status.frames }));
}

// Asks for every frame of the run and waits until the page holds them all (and their digests).
async function receiveAll(page, frames) {
  await page.evaluate((n) => { for (let k = 0; k < n; k++) window.studio.ask(k); }, frames);
  await page.waitForFunction((n) => window.studio.received.size === n, frames, { timeout: 30000 });
}

// Shows frame k and waits until it is drawn.
async function showFrame(page, k) {
  await page.evaluate((f) => { window.studio.playing = false; window.studio.seek(f); }, k);
  await page.waitForFunction((f) => window.studio.shown === f, k, { timeout: 20000 });
  await page.waitForTimeout(300);
}

// Flock pixels (flying tets' blue: b well above r and g) inside the flock's projected box and outside it.
async function flockPixels(page, file) {
  const png = await page.screenshot({ path: file });
  return page.evaluate(async ({ data }) => {
    const img = new Image();
    img.src = `data:image/png;base64,${data}`;
    await img.decode();
    const c = document.createElement('canvas'); c.width = img.width; c.height = img.height;
    const x = c.getContext('2d'); x.drawImage(img, 0, 0);
    const px = x.getImageData(0, 0, c.width, c.height).data;
    const box = window.studio.flockBox();
    let inside = 0, outside = 0;
    for (let y = 0; y < c.height; y++) for (let i = 0; i < c.width; i++) {
      const o = 4 * (y * c.width + i), r = px[o], g = px[o + 1], b = px[o + 2];
      if (!(b > r + 60 && b > g + 15)) continue;
      if (i >= box.x0 && i <= box.x1 && y >= box.y0 && y <= box.y1) inside++; else outside++;
    }
    return { inside, outside, box };
  }, { data: png.toString('base64') });
}

// A real mouse drag: press at a, move in steps to b, release.
async function drag(page, a, b, steps = 12) {
  await page.mouse.move(a.x, a.y);
  await page.mouse.down();
  for (let i = 1; i <= steps; i++) await page.mouse.move(a.x + ((b.x - a.x) * i) / steps, a.y + ((b.y - a.y) * i) / steps);
  await page.mouse.up();
}

// Drags the first control point (of a shot's group g, or the top level's) and returns where it went.
async function dragControlPoint(page, before, g = -1) {
  const h = await page.evaluate(() => window.studio.path.handleOnScreen(0));
  await page.mouse.click(h.x, h.y); // selects it: the gizmo appears round it
  // drawn twice with the gizmo (its picking shapes are placed as it is drawn): on a loaded machine
  // 200 ms may pass before the page draws at all
  await page.waitForFunction(() => window.studio.path.gizmo.object, null, { timeout: 10000 });
  await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
  await page.waitForTimeout(200);
  await drag(page, h, { x: h.x + 60, y: h.y - 70 }); // the gizmo's centre moves it in the view plane
  const first = ({ group }) => (group >= 0 ? window.studio.scene.groups[group] : window.studio.scene).path.points[0];
  await page.waitForFunction(({ group, p }) => JSON.stringify((group >= 0 ? window.studio.scene.groups[group]
    : window.studio.scene).path.points[0]) !== JSON.stringify(p), { group: g, p: before }, { timeout: 10000 });
  return page.evaluate(first, { group: g });
}

// The smallest distance from any agent's centroid, over the page's frames, to p.
function nearestCentroid(page, p, frames) {
  return page.evaluate(({ p, frames }) => {
    let best = Infinity;
    for (let k = 0; k < frames; k++) {
      const v = window.studio.frames.get(k).attrs[1];
      for (let a = 0; a < v.length; a += 12) {
        const cx = (v[a] + v[a + 3] + v[a + 6] + v[a + 9]) / 4, cy = (v[a + 1] + v[a + 4] + v[a + 7] + v[a + 10]) / 4;
        const cz = (v[a + 2] + v[a + 5] + v[a + 8] + v[a + 11]) / 4;
        best = Math.min(best, Math.hypot(cx - p[0], cy - p[1], cz - p[2]));
      }
    }
    return best;
  }, { p, frames });
}

// Drags a panel slider with the mouse across `steps` values (a drag sends edits as it goes; the
// server cancels the runs they make stale) and returns the value it ends on.
async function dragSlider(page, name, toFraction) {
  const box = await controller(page, name).locator('.lil-slider').boundingBox();
  const y = box.y + box.height / 2;
  await drag(page, { x: box.x + 2, y }, { x: box.x + box.width * toFraction, y }, 20);
  return page.evaluate((key) => window.studio.panel.values[key], name);
}

async function sketch(page) {
  await page.locator('.lil-controller', { hasText: 'Sketch path' }).locator('input').check();
  const ends = await page.evaluate(() => window.studio.path.endsOnScreen());
  const a = ends[0], b = ends[1], mid = { x: (a.x + b.x) / 2, y: (a.y + b.y) / 2 - 120 };
  await page.mouse.move(a.x, a.y);
  await page.mouse.down();
  for (let i = 1; i <= 20; i++) { // a bow over the straight line, through mid
    const t = i / 20, u = 1 - t;
    await page.mouse.move(u * u * a.x + 2 * u * t * mid.x + t * t * b.x, u * u * a.y + 2 * u * t * (2 * mid.y - (a.y + b.y) / 2) + t * t * b.y);
  }
  await page.mouse.up();
  await page.locator('.lil-controller', { hasText: 'Sketch path' }).locator('input').uncheck();
}

async function refused(browser, url) {
  const page = await browser.newPage();
  const wrong = url.replace(/\/[0-9a-f]{32}\//, `/${'0'.repeat(32)}/`);
  const response = await page.goto(wrong);
  check(response.status() === 403, `a wrong token got ${response.status()}, not 403`);
  await page.route('http://foreign.example/**', (route) => route.fulfill({ body: '<html><body>elsewhere</body></html>', contentType: 'text/html' }));
  await page.goto('http://foreign.example/');
  const opened = await page.evaluate((ws) => new Promise((resolve) => {
    const s = new WebSocket(ws);
    s.onopen = () => resolve(true);
    s.onerror = s.onclose = () => resolve(false);
    setTimeout(() => resolve(false), 5000);
  }), url.replace('http://', 'ws://') + 'ws');
  check(!opened, 'a WebSocket from a foreign Origin was accepted');
  await page.close();
}

async function live(browser, studio, workdir) {
  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  page.on('pageerror', (e) => fail(`page error: ${e.message}`));
  await page.goto(studio.url);
  let run = await finishedRun(page);
  log(`live: ${run.frames} frames`);
  await showFrame(page, Math.floor(run.frames / 3));
  const pixels = await flockPixels(page, join(shots, 'studio-live.png'));
  log('flock pixels', JSON.stringify(pixels));
  check(pixels.inside > 2000 && pixels.inside > 20 * pixels.outside, `the canvas does not show the flock where it is: ${JSON.stringify(pixels)}`);

  const before = await page.evaluate(() => window.studio.scene.path.points[0]);
  const moved = await dragControlPoint(page, before);
  log('control point', JSON.stringify(before), '→', JSON.stringify(moved));
  run = await finishedRun(page, run.generation);
  await receiveAll(page, run.frames);
  const nearest = await nearestCentroid(page, moved, run.frames);
  log(`the route passes ${nearest.toFixed(3)} from the moved point`);
  check(nearest < 1.5, `the flock's route passes ${nearest} from the moved control point`);

  const speed = await dragSlider(page, 'speed0', 0.25);
  await page.waitForFunction((v) => window.studio.scene.speed0 === v, speed, { timeout: 10000 });
  const dragStart = run.generation;
  run = await finishedRun(page, run.generation);
  log(`speed0 dragged to ${speed}: ${run.generation - dragStart} runs`);

  await sketch(page);
  run = await finishedRun(page, run.generation);
  const sketched = await page.evaluate(() => window.studio.scene.path.points);
  check(sketched.length === 4, `the sketch gave ${sketched.length} control points, not 4`);
  await receiveAll(page, run.frames);
  const near = await nearestCentroid(page, sketched[1], run.frames);
  log(`sketched path ${JSON.stringify(sketched)}: the route passes ${near.toFixed(3)} from its second point`);
  check(near < 1.5, `the flock's route passes ${near} from the sketched path`);
  await showFrame(page, Math.floor(run.frames / 2));
  await page.screenshot({ path: join(shots, 'studio-sketch.png') });

  await page.locator('.lil-controller', { hasText: 'Save scene' }).locator('button').click();
  await page.waitForFunction(() => window.studio.note?.startsWith('saved') && !window.studio.status.dirty, null, { timeout: 10000 });
  await receiveAll(page, run.frames);
  const received = await page.evaluate((n) => Array.from({ length: n }, (_, k) => window.studio.received.get(k)), run.frames);
  await page.close();
  return received;
}

// A shot of two groups, the second with its own path point. (scene keys as test_studio_server's shot)
const SHOT = { time: { frame_rate: 24, frame_limit: 24 }, speed0: 12.0, launch_rate: 800, seed: 7, path: { points: [[0, -6, 6]] },
  groups: [{ name: 'a', source: { mesh: 'cylinder.obj', translate: [-15, 0, 0] }, target: { mesh: 'sphere.obj', translate: [15, 0, 0] } },
    { name: 'b', start: 0.5, source: { mesh: 'sphere.obj', translate: [-15, -12, 0] },
      target: { mesh: 'cylinder.obj', translate: [15, -12, 0] }, path: { points: [[0, -18, 4]] } }] };

// A shot: group 1 picked in the panel, the handles are its own path point between its own shapes,
// a drag of it edits groups.1.path.points and its speed0 slider groups.1.speed0; Save, and
// `flockmorph run` of the saved scene writes byte for byte the frames the page received.
async function shotGroups(browser) {
  const scene = join(tmp, 'shot.json');
  writeFileSync(scene, JSON.stringify(SHOT));
  const studio = await startStudio(cli, scene);
  let received, speed;
  try {
    const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
    page.on('pageerror', (e) => fail(`page error: ${e.message}`));
    await page.goto(studio.url);
    let run = await finishedRun(page);
    await controller(page, 'Edit').locator('select').selectOption({ label: 'group 1: b' });
    const path = await page.evaluate(() => ({ points: window.studio.path.points.map((p) => p.toArray()),
      ends: window.studio.path.ends.map((e) => e.toArray()) }));
    log('group 1 picked: handles', JSON.stringify(path.points), 'ends', JSON.stringify(path.ends.map((e) => e.map(Math.round))));
    check(JSON.stringify(path.points) === '[[0,-18,4]]', `the handles are not group 1's own path point: ${JSON.stringify(path.points)}`);
    check(path.ends.every((e) => Math.abs(e[1] + 12) < 1), `the path's ends are not group 1's shapes: ${JSON.stringify(path.ends)}`);
    const moved = await dragControlPoint(page, [0, -18, 4], 1);
    const top = await page.evaluate(() => window.studio.scene.path.points);
    log(`group 1's control point dragged to ${JSON.stringify(moved)}; the top level's stays ${JSON.stringify(top)}`);
    check(JSON.stringify(top) === JSON.stringify(SHOT.path.points), `the drag moved the top level's path: ${JSON.stringify(top)}`);
    await dragSlider(page, 'speed0', 0.25);
    // under load the slider's last input may land after the drag returns: the value is the one the
    // panel holds once it has sent every edit (twice the 120 ms throttle with nothing pending)
    await page.waitForFunction(() => !window.studio.panel.timer && window.studio.panel.pending.size === 0, null, { timeout: 10000 });
    await page.waitForTimeout(300);
    await page.waitForFunction(() => !window.studio.panel.timer && window.studio.panel.pending.size === 0, null, { timeout: 10000 });
    speed = await page.evaluate(() => window.studio.panel.values.speed0);
    await page.waitForFunction((v) => window.studio.scene.groups[1].speed0 === v, speed, { timeout: 10000 });
    run = await finishedRun(page, run.generation);
    await showFrame(page, Math.floor(run.frames * 0.75));
    await page.screenshot({ path: join(shots, 'studio-shot.png') });
    await controller(page, 'Save scene').locator('button').click();
    await page.waitForFunction(() => window.studio.note?.startsWith('saved') && !window.studio.status.dirty, null, { timeout: 10000 });
    await receiveAll(page, run.frames);
    received = await page.evaluate((n) => Array.from({ length: n }, (_, k) => window.studio.received.get(k)), run.frames);
    await followGroups(page);
    await page.close();
  } finally { await stopStudio(studio); }
  const saved = JSON.parse(readFileSync(scene, 'utf8'));
  check(saved.groups[1].speed0 === speed && saved.speed0 === SHOT.speed0 && saved.groups[0].speed0 === undefined,
    `the saved shot does not carry groups[1].speed0 = ${speed} alone: ${JSON.stringify(saved)}`);
  check(JSON.stringify(saved.groups[1].path.points[0]) !== JSON.stringify(SHOT.groups[1].path.points[0]) && !saved.groups[0].path,
    `the saved shot does not carry group 1's dragged point alone: ${JSON.stringify(saved)}`);
  sameFrames(scene, join(tmp, 'shot_out'), received, 'shot');
}

// An edit of the `groups` list itself (sent on the page's socket, as another tab's edit comes): the
// "Edit" list offers the groups as they are now, a new group picked shows its own handle between its
// own shapes, and a picked group that is removed gives way to the top level and its handle.
async function followGroups(page) {
  const select = controller(page, 'Edit').locator('select');
  const shown = () => select.evaluate((s) => ({ options: [...s.options].map((o) => o.text), picked: s.options[s.selectedIndex]?.text }));
  const edit = (groups) => page.evaluate((g) => window.studio.connection.send({ type: 'set', key: 'groups', value: g }), groups);
  const handles = () => page.evaluate(() => JSON.stringify(window.studio.path.points.map((p) => p.toArray())));
  const two = await page.evaluate(() => window.studio.scene.groups);
  await edit([...two, { name: 'c', start: 0.5, source: { mesh: 'sphere.obj', translate: [-15, 12, 0] },
    target: { mesh: 'cylinder.obj', translate: [15, 12, 0] }, path: { points: [[0, 18, 4]] } }]);
  await page.waitForFunction(() => window.studio.scene.groups.length === 3, null, { timeout: 10000 });
  const three = await shown();
  check(three.options.length === 4 && three.options[3] === 'group 2: c' && three.picked === 'group 1: b',
    `the Edit list does not follow a third group (group 1 still picked): ${JSON.stringify(three)}`);
  await select.selectOption({ label: 'group 2: c' });
  check(await handles() === '[[0,18,4]]', `group 2's handle is not its own path point: ${await handles()}`);
  await page.waitForFunction(() => window.studio.path.ends.every((e) => Math.abs(e.y - 12) < 1), null, { timeout: 20000 });
  await edit(two);
  await page.waitForFunction(() => window.studio.scene.groups.length === 2, null, { timeout: 10000 });
  const back = await shown();
  check(back.options.length === 3 && back.picked === 'top level (every group)' && await handles() === JSON.stringify(SHOT.path.points),
    `group 2 removed: the Edit list and handles do not give way to the top level: ${JSON.stringify(back)} ${await handles()}`);
  log('an edit of groups: the Edit list followed (3 groups, then 2), the handles with it');
}

// `flockmorph run` of the saved scene writes, byte for byte, the frames the page received.
function sameFrames(scene, out, received, what) {
  const run = spawnSync(cli, ['run', scene, '-o', out, '--quiet'], { encoding: 'utf8' });
  check(run.status === 0, `${what}: flockmorph run of the saved scene: ${run.stderr}`);
  const facts = cacheFacts(join(out, 'frames.fmc'));
  check(facts.frames === received.length, `${what}: run wrote ${facts.frames} frames, the page received ${received.length}`);
  const differ = facts.sha256.findIndex((h, k) => h !== received[k]);
  check(differ < 0, `${what}: frame ${differ}: flockmorph run's bytes differ from what the page received`);
  log(`${what}: flockmorph run of the saved scene: all ${facts.frames} frames byte-identical to the page's`);
  return facts;
}

// The panel's row of the control named `name`.
function controller(page, name) {
  return page.locator('.lil-controller', { has: page.locator('.lil-name', { hasText: new RegExp(`^${name}$`) }) });
}

async function playback(browser, cache, k, expected) {
  const studio = await startStudio(cli, cache);
  try {
    const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
    await page.goto(studio.url);
    await page.waitForFunction(() => window.studio.status.stage === 'playback', null, { timeout: 20000 });
    await showFrame(page, k);
    const values = await page.evaluate((f) => Array.from(window.studio.frames.get(f).attrs[1]), k);
    check(values.length === expected.length && values.every((v, i) => v === expected[i]),
      `playback frame ${k} differs from the Python reader's`);
    await page.screenshot({ path: join(shots, 'studio-playback.png') });
    await page.close();
  } finally { await stopStudio(studio); }
}

// A point flock's playback: the dots (disc shader) show where the agents are, and cover about the
// pixels three.js's textured sprites (the page's first drawing) covered, and nothing outside the
// agents' box changes between the two.
async function pointFlock(browser) {
  const out = join(tmp, 'points');
  const scene = join(source, 'examples', 'flock_cylinder_sphere', 'scene.json');
  const r = spawnSync(cli, ['run', scene, '-o', out, '--set', 'n=600', '--set', 'time.frame_limit=48'], { encoding: 'utf8' });
  check(r.status === 0, `flockmorph run of the point flock: ${r.stderr}`);
  const studio = await startStudio(cli, join(out, 'frames.fmc'));
  try {
    const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
    await page.goto(studio.url);
    await page.waitForFunction(() => window.studio.status.stage === 'playback', null, { timeout: 20000 });
    await showFrame(page, 40);
    const disc = await flockPixels(page, join(tmp, 'points-disc.png'));
    await page.evaluate(() => window.studio.view.setPointStyle('sprite'));
    await page.waitForTimeout(300);
    const sprite = await flockPixels(page, join(tmp, 'points-sprite.png'));
    log('point flock pixels: disc', JSON.stringify(disc), 'sprite', JSON.stringify(sprite));
    // outside the agents' box: the timeline's and the panel's blue, the same in both pictures
    check(disc.inside > 1000 && disc.outside === sprite.outside, `the dots are not where the agents are: ${JSON.stringify(disc)}`);
    check(Math.abs(disc.inside - sprite.inside) < 0.1 * sprite.inside,
      `the dots cover ${disc.inside} pixels, the sprites ${sprite.inside}`);
    await page.close();
  } finally { await stopStudio(studio); }
}

async function main() {
  if (arg('--skip')) skip(arg('--skip'));
  if (!existsSync(CHROMIUM)) skip(`no ${CHROMIUM} (Debian's chromium: tools/setup.sh installs it)`);
  const pw = playwright(source);
  if (!pw) skip('no playwright-core in web/node_modules (npm ci in web/: tools/setup.sh)');
  if (!existsSync(join(dirname(cli), 'studio', 'index.html'))) skip('the page is not built (node and npm ci: tools/setup.sh)');
  rmSync(tmp, { recursive: true, force: true });
  mkdirSync(tmp, { recursive: true });
  mkdirSync(shots, { recursive: true });
  const scene = join(tmp, 'scene.json');
  copyFileSync(join(source, 'tests', 'studio', 'scene_small.json'), scene);
  for (const m of ['cylinder.obj', 'sphere.obj']) copyFileSync(join(source, 'examples', 'flock_cylinder_sphere', m), join(tmp, m));
  const original = readFileSync(scene, 'utf8');

  const browser = await launchChromium(pw);
  try {
    const studio = await startStudio(cli, scene);
    let received;
    try {
      await refused(browser, studio.url);
      received = await live(browser, studio, tmp);
    } finally { await stopStudio(studio); }
    check(readFileSync(scene, 'utf8') !== original, 'Save did not write the scene file');
    const facts = sameFrames(scene, join(tmp, 'out'), received, 'live');
    const k = Math.floor(facts.frames / 2);
    await playback(browser, join(tmp, 'out', 'frames.fmc'), k, cacheFacts(join(tmp, 'out', 'frames.fmc'), '--frame', String(k)).frame);
    log(`playback: frame ${k} equals the Python reader's`);
    await shotGroups(browser);
    await pointFlock(browser);
  } finally { await browser.close(); }
  log('test_studio_browser: OK');
}

main().catch((e) => { if (!process.exitCode) { console.error(e); process.exitCode = 1; } });
