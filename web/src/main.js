// flockmorph studio's page (docs/studio.md): one app object that ties the connection, the view,
// the path editor, the panel and the timeline together. Frames are asked for one at a time (a few
// ahead while playing) and kept for scrubbing; a new run (generation) drops the old ones.
import { Connection, ATTR } from './protocol.js';
import { View } from './view.js';
import { PathEditor } from './path.js';
import { Panel, scopedKey } from './panel.js';
import { Timeline } from './timeline.js';

const AHEAD = 4;                   // frames asked for before they are due, to hide the round trip
const KEEP_BYTES = 768 * 2 ** 20;  // frames kept in the page for scrubbing

class App {
  constructor() {
    this.connection = new Connection();
    this.view = new View(document.getElementById('viewport'));
    this.path = new PathEditor(this.view, (points) => this.connection.send({ type: 'set', key: scopedKey(this.path.editGroup, 'path.points'), value: points }));
    this.panel = new Panel(this);
    this.timeline = new Timeline(this);
    this.frames = new Map(); // k → parsed frame of this generation
    this.keptBytes = 0;
    this.asked = new Set();
    this.generation = -1;
    this.status = { frames: 0, stage: 'connecting' };
    this.shapes = [];
    this.current = 0;       // the frame shown (or to show)
    this.shown = -1;
    this.playing = true;
    this.follow = true;
    this.fastest = false;
    this.clock = 0;
    this.shownAt = -Infinity;
    this.counter = { frames: 0, since: performance.now(), fps: 0 };
    this.errors = [];
    this.received = new Map(); // k → SHA-256 of the main attribute's bytes (tests: the page got these bytes)
    this.listen();
    requestAnimationFrame((t) => this.tick(t));
  }

  listen() {
    const c = this.connection;
    c.addEventListener('hello', (e) => { this.hello = e.detail; this.scene = e.detail.scene; this.panel.build(e.detail); });
    c.addEventListener('status', (e) => this.onStatus(e.detail));
    c.addEventListener('shapes', (e) => this.onShapes(e.detail.shapes));
    c.addEventListener('scene', (e) => this.onScene(e.detail));
    c.addEventListener('saved', (e) => this.setStatusNote(`saved ${e.detail.path}`));
    c.addEventListener('render', (e) => this.onRender(e.detail));
    c.addEventListener('error', (e) => this.onError(e.detail));
    c.addEventListener('frame', (e) => this.onFrame(e.detail));
    c.addEventListener('closed', () => this.setStatusNote('disconnected: the studio has stopped'));
  }

  onStatus(s) {
    if (s.generation !== this.generation) { this.dropFrames(); this.generation = s.generation; }
    this.status = s;
    this.timeline.setLength(s.frames);
    this.renderStatus();
  }

  onShapes(shapes) {
    const first = this.shapes.length === 0;
    this.shapes = shapes;
    this.view.setShapes(shapes);
    if (first) this.view.frameShapes();
    if (this.scene) this.path.setScene(this.scene, shapes);
  }

  onScene(m) {
    this.scene = m.scene;
    if (this.panel.followGroups(m.scene)) this.path.editGroup = this.panel.group; // `groups` edited
    this.path.setScene(m.scene, this.shapes);
    this.panel.refresh(m.scene);
    this.status.dirty = m.dirty;
    this.renderStatus();
  }

  // A shot: the group the panel and the path's handles edit (-1: the top level).
  selectGroup(k) {
    this.panel.selectGroup(k, this.scene);
    this.path.editGroup = k;
    this.path.setScene(this.scene, this.shapes);
  }

  dropFrames() {
    this.frames.clear();
    this.asked.clear();
    this.received.clear();
    this.keptBytes = 0;
    this.shown = -1;
    this.current = 0;
  }

  onFrame(f) {
    this.asked.delete(f.k);
    if (f.generation !== this.generation && this.hello?.mode === 'live') return; // a run an edit replaced
    this.frames.set(f.k, f);
    this.keptBytes += f.buffer.byteLength;
    for (const k of this.frames.keys()) { // the oldest asked first go first
      if (this.keptBytes <= KEEP_BYTES) break;
      if (k === this.current) continue;
      this.keptBytes -= this.frames.get(k).buffer.byteLength;
      this.frames.delete(k);
    }
    this.digest(f);
  }

  async digest(f) {
    const main = f.attrs[ATTR.TET_VERTICES] ?? f.attrs[ATTR.POSITION];
    if (!main || !crypto.subtle) return;
    const bytes = new Uint8Array(main.buffer, main.byteOffset, main.byteLength);
    const hash = new Uint8Array(await crypto.subtle.digest('SHA-256', bytes));
    this.received.set(f.k, [...hash].map((b) => b.toString(16).padStart(2, '0')).join(''));
  }

  ask(k) {
    if (k < 0 || k >= this.status.frames || this.frames.has(k) || this.asked.has(k)) return;
    this.asked.add(k);
    this.connection.send({ type: 'frame', k });
  }

  // The frame due now: at the scene's frame rate (or as fast as frames come), up to the last one
  // simulated; following a live run, it waits at the end for more.
  advance(dt) {
    const last = this.status.frames - 1;
    if (!this.playing || last < 0) return;
    if (this.fastest) {
      if (this.current < last && this.frames.has(this.current + 1)) this.current += 1;
    } else {
      this.clock = Math.min(this.clock + dt * (this.status.frame_rate || 24), 2);
      while (this.clock >= 1 && this.current < last && this.frames.has(this.current + 1)) { this.clock -= 1; this.current += 1; }
    }
    if (this.current >= last && !this.follow && this.status.stage !== 'running' && this.status.stage !== 'building') this.playing = false;
  }

  tick(t) {
    const dt = this.last ? (t - this.last) / 1000 : 0;
    this.last = t;
    this.advance(dt);
    for (let k = this.current; k < this.current + (this.playing ? AHEAD : 1); k++) this.ask(k);
    this.findRestShapes();
    if (this.current !== this.shown && this.frames.has(this.current)) this.show(this.current);
    else if (!this.view.framed && !this.shapes.length && this.shown >= 0) this.frameOnFlock();
    // playing for the dynamic resolution: a frame was shown in the last half second (following a
    // live run, the timeline waits for frames at its end without going back to full resolution)
    this.view.render(this.playing && t - this.shownAt < 500, this.status.frame_rate || 24, this.counter.fps);
    // The bar's numbers ten times a second while playing (each write lays out and paints it again:
    // 4 ms a frame in software), at once otherwise.
    if (!this.playing || !(t - this.timelineAt < 100)) { this.timeline.update(); this.timelineAt = t; }
    requestAnimationFrame((time) => this.tick(time));
  }

  show(k) {
    const f = this.frames.get(k);
    this.view.showFrame(f, this.frames.get(k - 1));
    if (!this.view.framed && !this.shapes.length) this.frameOnFlock();
    this.shown = k;
    const c = this.counter, now = performance.now();
    this.shownAt = now;
    this.shownCount = (this.shownCount ?? 0) + 1; // frames shown so far (the benchmark's processor time a frame)
    c.frames += 1;
    if (now - c.since >= 1000) { c.fps = (c.frames * 1000) / (now - c.since); c.frames = 0; c.since = now; }
  }

  redraw() { this.shown = -1; }

  // The shapes the tets rest in, for the view to draw as their surface: the run's first frame (the
  // source) and, once the run has ended, its last (the target), each found once a run.
  findRestShapes() {
    const s = this.status, ended = s.stage === 'finished' || s.stage === 'playback';
    if (s.kind === 'points' || s.frames < 1) return;
    [0, ended ? s.frames - 1 : -1].forEach((k, i) => {
      const tag = `${this.generation}:${k}`;
      if (k < 0 || this.view.restTags[i] === tag) return;
      if (this.frames.has(k)) this.view.setRestShape(i, this.frames.get(k), tag);
      else this.ask(k);
    });
  }

  // No shapes to frame (a played cache): the first and last frames, once both are here.
  frameOnFlock() {
    const ends = [0, this.status.frames - 1];
    ends.forEach((k) => this.ask(k));
    if (!ends.every((k) => this.frames.has(k))) return;
    this.view.framePositions(ends.map((k) => { const f = this.frames.get(k); return f.attrs[ATTR.TET_VERTICES] ?? f.attrs[ATTR.POSITION]; }));
  }

  // The shown flock's box on the page, in CSS pixels (tests look for its pixels there).
  flockBox() {
    const f = this.frames.get(this.shown), box = { x0: Infinity, y0: Infinity, x1: -Infinity, y1: -Infinity };
    const v = f && (f.attrs[ATTR.TET_VERTICES] ?? f.attrs[ATTR.POSITION]);
    if (!v) return box;
    for (let i = 0; i < v.length; i += 3) {
      const p = this.path.onScreen(v[i], v[i + 1], v[i + 2]);
      box.x0 = Math.min(box.x0, p.x - 8); box.x1 = Math.max(box.x1, p.x + 8);
      box.y0 = Math.min(box.y0, p.y - 8); box.y1 = Math.max(box.y1, p.y + 8);
    }
    return box;
  }

  seek(k) {
    this.current = Math.max(0, Math.min(k, this.status.frames - 1));
    this.clock = 0;
  }

  renderStatus() {
    const s = this.status, name = this.hello?.name ?? '';
    const dirty = s.dirty ? ' · edited, not saved' : '';
    const failure = s.failure ? `\n${s.failure}` : '';
    document.getElementById('status').textContent =
      `${name} · ${s.stage} · ${s.frames} frames · ${s.agents} ${s.kind || 'agents'}${dirty}${this.note ? ` · ${this.note}` : ''}${failure}`;
  }

  setStatusNote(text) { this.note = text; this.renderStatus(); }

  // The Render button's run: its progress line, then where it wrote or why it failed.
  onRender(r) {
    this.render = r;
    if (r.state === 'running') this.setStatusNote(`render: ${r.line}`);
    else if (r.state === 'finished') this.setStatusNote(`rendered: ${r.output}`);
    else { this.setStatusNote(`render failed (exit ${r.exit})`); this.showError(`render: ${r.line}`); }
  }

  // A frame asked of a run that an edit has just replaced is not there yet in the new run: the
  // next status drops the old run's frames and asks are made again, so that is not the user's error.
  onError(e) {
    if (e.request === 'frame' && e.message.includes('is not simulated yet')) return;
    this.showError(e.message);
  }

  showError(message) {
    this.errors.push(message);
    const box = document.getElementById('errors'), div = document.createElement('div');
    div.textContent = message;
    box.appendChild(div);
    setTimeout(() => div.remove(), 8000);
  }
}

// One app object; tests read it (window.studio) through Playwright.
window.studio = new App();
