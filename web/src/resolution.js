// Dynamic resolution, as games do it: while the flock plays, the canvas is drawn at a lower pixel
// ratio whenever the measured cost of a drawn frame is over the budget the scene's frame rate
// sets, and at full resolution again when it is paused (or the cost falls well under budget).
// Software WebGL (SwiftShader, a laptop's integrated GPU) spends most of a frame on pixels, so a
// quarter of them (ratio 0.5) costs about a quarter of the time. docs/studio.md, "Frame rate".

// The steps, as fractions of the device's pixel ratio.
export const RATIOS = [1, 0.75, 0.5, 0.35];

export class DynamicResolution {
  // budgetMs: a drawn frame's allowed cost; window: frames averaged; holdMs: the least time between
  // two changes (each change resizes the canvas's buffer, which costs a frame of its own).
  constructor({ window = 8, holdMs = 700, margin = 0.9 } = {}) {
    this.window = window;
    this.holdMs = holdMs;
    this.margin = margin;
    this.step = 0;
    this.costs = [];
    this.changedAt = -Infinity;
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
  // playing at rate frames/s. True when the ratio changes: the caller resizes and draws again.
  measure(costMs, now, rate) {
    this.costs.push(costMs);
    if (this.costs.length > this.window) this.costs.shift();
    if (this.costs.length < this.window || now - this.changedAt < this.holdMs) return false;
    const mean = this.costs.reduce((a, b) => a + b, 0) / this.costs.length;
    const budget = (1000 / Math.max(1, rate || 24)) * this.margin;
    let next = this.step;
    if (mean > budget && this.step < RATIOS.length - 1) next = this.step + 1;
    // Up only where the larger canvas (cost by pixels: the ratio squared) would still fit.
    else if (this.step > 0 && mean * (RATIOS[this.step - 1] / RATIOS[this.step]) ** 2 < 0.8 * budget) next = this.step - 1;
    if (next === this.step) return false;
    this.step = next;
    this.costs.length = 0;
    this.changedAt = now;
    return true;
  }
}
