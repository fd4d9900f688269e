// The timeline: play and pause (space), a frame back and on (arrow keys), back to the start, and
// the scrub bar over every frame simulated so far.
export class Timeline {
  constructor(app) {
    this.app = app;
    this.el = (id) => document.getElementById(id);
    this.el('play').onclick = () => this.toggle();
    this.el('back').onclick = () => app.seek(0);
    this.el('step').onclick = () => { app.playing = false; app.seek(app.current + 1); };
    this.el('step-back').onclick = () => { app.playing = false; app.seek(app.current - 1); };
    this.el('scrub').oninput = (e) => { app.playing = false; app.seek(Number(e.target.value)); };
    window.addEventListener('keydown', (e) => {
      if (e.target.tagName === 'INPUT' && e.target.type !== 'range') return;
      if (e.key === ' ') { e.preventDefault(); this.toggle(); }
      if (e.key === 'ArrowRight') this.el('step').onclick();
      if (e.key === 'ArrowLeft') this.el('step-back').onclick();
    });
  }

  toggle() {
    const app = this.app;
    if (!app.playing && app.current >= app.status.frames - 1) app.seek(0); // play again from the start
    app.playing = !app.playing;
  }

  setLength(frames) { this.el('scrub').max = String(Math.max(0, frames - 1)); }

  // Called every animation frame: the DOM is written only where a value changed (a write makes the
  // browser lay out and paint the bar again).
  update() {
    const app = this.app, ratio = app.view.resolution.ratio; // the dynamic resolution's, while playing
    this.set('scrub', 'value', String(app.current));
    this.set('frame-label', 'textContent', `${app.shown < 0 ? '–' : app.shown} / ${Math.max(0, app.status.frames - 1)}`);
    this.set('play', 'textContent', app.playing ? '||' : '▶');
    this.set('fps', 'textContent', `${app.counter.fps.toFixed(1)} fps`);
    this.set('resolution', 'textContent', ratio < 1 ? `${Math.round(100 * ratio)} % res` : '');
  }

  set(id, property, value) {
    const el = this.el(id);
    if (el[property] !== value) el[property] = value;
  }
}
