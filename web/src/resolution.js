// Dynamic resolution, as games do it: while the flock plays, the canvas is drawn at a lower pixel
// ratio whenever the measured cost of a drawn frame is over the budget the scene's frame rate
// sets, and at full resolution again when it is paused (or the cost falls well under budget).
// Software WebGL (SwiftShader, a laptop's integrated GPU) spends most of a frame on pixels, so a
// quarter of them (ratio 0.5) costs about a quarter of the time. docs/studio.md, "Frame rate".

// The steps, as fractions of the device's pixel ratio.
export const RATIOS = [1, 0.75, 0.5, 0.35];

// A step down that saves less than this share of the frame's cost is undone and not tried again
// for PIN_MS: where pixels are not what a frame costs (a small flock, a loaded machine), a smaller
// canvas only costs its resizes.
const HELPED = 0.9;
const PIN_MS = 10000;

export class DynamicResolution {
  // window: frames averaged; holdMs: the least time between two changes (each change resizes the
  // canvas's buffer, which costs a frame of its own); margin: the share of 1 / rate a frame may cost.
  constructor({ window = 8, holdMs = 1000, margin = 0.9 } = {}) {
    this.window = window;
    this.holdMs = holdMs;
    this.margin = margin;
    this.step = 0;
    this.costs = [];
    this.changedAt = -Infinity;
    this.above = [];          // the mean cost measured at each step when it was left
    this.pinnedUntil = -Infinity;
  }

  get ratio() { return RATIOS[this.step]; }

  // The full resolution again (paused, or a still view): forgets the costs measured so far.
  full() {
    const changed = this.step !== 0;
    this.step = 0;
    this.costs.length = 0;
    return changed;
  }

  // A drawn frame cost costMs (from its draw to the next animation frame) at time now, while
  // playing at rate frames/s and showing shown frames a second (the page's counter; omitted: too
  // few). It steps down only while the page shows fewer than the rate: on a
  // loaded machine a frame's measured cost holds the waits for a processor too. True when the
  // ratio changes: the caller resizes and draws again.
  measure(costMs, now, rate, shown = 0) {
    this.costs.push(costMs);
    if (this.costs.length > this.window) this.costs.shift();
    if (this.costs.length < this.window || now - this.changedAt < this.holdMs) return false;
    const mean = this.costs.reduce((a, b) => a + b, 0) / this.costs.length;
    const budget = (1000 / Math.max(1, rate || 24)) * this.margin, behind = shown < 0.95 * (rate || 24);
    const before = this.above[this.step - 1];
    let next = this.step;
    if (this.step > 0 && before !== undefined && mean > budget && mean > HELPED * before) {
      next = this.step - 1; // the last step down did not pay: back, and stay there a while
      this.pinnedUntil = now + PIN_MS;
    } else if (mean > budget && behind && this.step < RATIOS.length - 1 && now >= this.pinnedUntil) next = this.step + 1;
    // Up only where the larger canvas (cost by pixels: the ratio squared) would still fit.
    else if (this.step > 0 && mean * (RATIOS[this.step - 1] / RATIOS[this.step]) ** 2 < 0.8 * budget) next = this.step - 1;
    if (next === this.step) return false;
    if (next > this.step) this.above[this.step] = mean;
    this.step = next;
    this.costs.length = 0;
    this.changedAt = now;
    return true;
  }
}
