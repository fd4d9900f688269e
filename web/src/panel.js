// The control panel (lil-gui): the scene's main parameters, Save, the sketch mode, the colouring
// and the playback speed. A parameter change is sent as {type: "set", key, value} (the server
// checks it as the scene loader does, and runs the scene again from the start). In a shot (a scene
// with `groups`) the parameters are the top level's or, once one is picked, a group's: its keys
// are sent as groups.K.KEY, and it shows the value the group flies with (its own, else the top
// level's, as the loader lays a group over the top level).
import GUI from 'lil-gui';

// [key, default (docs/scene.md), min, max, step]; shown for the modes listed.
const MORPH = 'tetra_morph', FLOCK = 'shape_flock';
const WHOLE_SHOT = ['time.']; // keys a group may not set (the whole shot shares them: docs/scene.md)
const NUMBERS = [
  ['n', 0, 0, 50000, 1, [MORPH, FLOCK]],
  ['speed0', 10, 0.5, 60, 0.1, [MORPH, FLOCK]],
  ['omega1', 1, 0.05, 5, 0.01, [MORPH]],
  ['launch_rate', 0, 0, 20000, 10, [MORPH]],
  ['style.omega2', 1, 0, 5, 0.01, [MORPH, FLOCK]],
  ['path.key_points', 32, 1, 200, 1, [MORPH, FLOCK]],
  ['path.width', 0, 0, 20, 0.1, [MORPH]],
  ['mde.d_min', 0, 0, 2, 0.01, [MORPH]],
  ['morph.shrink', 0.5, 0.05, 1, 0.01, [MORPH]],
  ['shape_flock.damping', 3, 0, 20, 0.1, [FLOCK]],
  ['shape_flock.external_gain', 1, 0, 10, 0.1, [FLOCK]],
  ['time.frame_limit', 600, 2, 5000, 1, [MORPH, FLOCK]],
];
const RANGES = [ // [lo, hi] values (the shape flock's per-agent ranges)
  ['shape_flock.max_speed', [12, 18], 0.5, 60],
  ['shape_flock.max_force', [40, 80], 1, 400],
  ['shape_flock.separation.weight', [0.4, 0.6], 0, 10],
  ['shape_flock.cohesion.weight', [0.1, 0.2], 0, 10],
  ['shape_flock.alignment.weight', [2, 3], 0, 10],
];
const FUZZY = ['steering', 'homing', 'damping', 'external'];

export function getKey(doc, key) {
  return key.split('.').reduce((o, k) => (o == null ? undefined : o[k]), doc);
}

// The key an edit of group's KEY sends (group -1: the top level's).
export function scopedKey(group, key) {
  return group >= 0 ? `groups.${group}.${key}` : key;
}

// The value group flies with: its own, else the top level's (group -1: the top level's).
export function groupValue(doc, group, key) {
  const own = group >= 0 ? getKey(doc.groups?.[group], key) : undefined;
  return own !== undefined ? own : getKey(doc, key);
}

// Whether group (-1: the top level) may set key: a group takes no `time` keys, and one that starts
// from another group's shape takes no n (it has that group's agents).
export function editable(doc, group, key) {
  if (group < 0) return true;
  if (WHOLE_SHOT.some((p) => key.startsWith(p))) return false;
  return !(key === 'n' && doc.groups?.[group]?.source?.group !== undefined);
}

// A shot's group names, in order ([] for a scene without groups).
export function groupNames(doc) {
  return Array.isArray(doc?.groups) ? doc.groups.map((g) => g?.name ?? '') : [];
}

export class Panel {
  constructor(app) {
    this.app = app;
    this.gui = new GUI({ title: 'flockmorph studio' });
    this.values = {};
    this.pending = new Map();
    this.timer = null;
    this.group = -1;      // the group edited (-1: the top level)
    this.folders = [];    // the parameters' folders, built again for another group
    this.groupChoice = null; // the shot's "Edit" list, and the group names it offers
    this.groupNames = [];
  }

  // Sends edits at most every 120 ms, the last value of each key (the server cancels a run an
  // edit makes stale; this only keeps a drag from flooding the socket).
  set(key, value) {
    this.pending.set(key, value);
    if (this.timer) return;
    this.timer = setTimeout(() => {
      this.timer = null;
      for (const [k, v] of this.pending) this.app.connection.send({ type: 'set', key: k, value: v });
      this.pending.clear();
    }, 120);
  }

  build(hello) {
    const gui = this.gui, app = this.app;
    const actions = { save: () => app.connection.send({ type: 'save' }), sketch: false, sketchPoints: 4,
      render: () => app.connection.send({ type: 'render' }),
      colourBy: 'phase', speed: 'scene rate', follow: true };
    if (hello.mode === 'live') {
      gui.add(actions, 'save').name('Save scene');
      if (hello.render) gui.add(actions, 'render').name('Render (flockmorph run of the saved scene)');
      gui.add(actions, 'sketch').name('Sketch path').onChange((v) => app.path.setSketching(v));
      gui.add(actions, 'sketchPoints', 1, 16, 1).name('Sketch points').onChange((v) => { app.path.sketchPoints = v; });
    }
    gui.add(actions, 'colourBy', ['phase', 'speed', 'group', 'id']).name('Colour by').onChange((v) => {
      app.view.colourBy = v; app.redraw();
    });
    gui.add(actions, 'speed', ['scene rate', 'as fast as it can']).name('Playback').onChange((v) => { app.fastest = v !== 'scene rate'; });
    gui.add(actions, 'follow').name('Follow the run').onChange((v) => { app.follow = v; });
    if (hello.mode === 'live') this.buildGroupChoice(hello.scene);
    if (hello.mode === 'live') this.buildParameters(hello.scene);
    if (hello.cache) this.buildCacheFacts(hello.cache);
  }

  // A shot: which of its groups the parameters and the path's handles edit (none for a scene).
  buildGroupChoice(doc) {
    this.groupNames = groupNames(doc);
    if (!this.groupNames.length) return;
    const options = { 'top level (every group)': -1 };
    this.groupNames.forEach((name, k) => { options[`group ${k}: ${name}`] = k; });
    this.groupChoice = this.gui.add(this, 'group', options).name('Edit').onChange((k) => this.app.selectGroup(k));
  }

  // An edit of `groups` (added, removed or renamed; this tab's or another's): the "Edit" list offers
  // the groups as they are now, and the parameters follow; a picked group that is gone gives way to
  // the top level. Rebuilt in place of the old list, before the parameters' folders. Returns whether
  // it changed.
  followGroups(doc) {
    if (JSON.stringify(groupNames(doc)) === JSON.stringify(this.groupNames)) return false;
    this.groupChoice?.destroy();
    this.groupChoice = null;
    for (const f of this.folders) f.destroy();
    this.folders = [];
    if (this.group >= (doc.groups?.length ?? 0)) this.group = -1;
    this.buildGroupChoice(doc);
    this.selectGroup(this.group, doc);
    return true;
  }

  // The parameters of another group (or the top level), from the scene as it is now.
  selectGroup(k, doc) {
    this.group = k;
    for (const f of this.folders) f.destroy();
    this.folders = [];
    this.values = {};
    this.buildParameters(doc);
  }

  // A folder of the parameters (destroyed when another group is picked).
  folder(title) {
    const f = this.gui.addFolder(this.group >= 0 ? `${title} (group ${this.group})` : title);
    this.folders.push(f);
    return f;
  }

  // The value the edited group flies with, and the key its edit sends.
  value(doc, key) { return groupValue(doc, this.group, key); }
  setScoped(key, value) { this.set(scopedKey(this.group, key), value); }

  // A played cache's facts and, where a stats.json lies beside it, the run's plain values.
  buildCacheFacts(cache) {
    const show = (folder, facts) => {
      for (const [k, v] of Object.entries(facts)) {
        if (v === null || typeof v === 'object') continue;
        folder.add({ [k]: Array.isArray(v) ? v.join(', ') : v }, k).disable();
      }
    };
    const folder = this.gui.addFolder('Cache');
    show(folder, { ...cache, attributes: cache.attributes.join(', ') });
    if (cache.stats) show(this.gui.addFolder('stats.json').close(), cache.stats);
  }

  buildParameters(doc) {
    const mode = doc.mode ?? MORPH;
    const folder = this.folder('Scene');
    for (const [key, def, min, max, step, modes] of NUMBERS) {
      if (!modes.includes(mode) || !editable(doc, this.group, key)) continue;
      this.values[key] = this.value(doc, key) ?? def;
      folder.add(this.values, key, min, max, step).name(key).onChange((v) => this.setScoped(key, v));
    }
    this.values['path.curve'] = this.value(doc, 'path.curve') ?? 'polyline';
    folder.add(this.values, 'path.curve', ['polyline', 'catmull_rom']).onChange((v) => this.setScoped('path.curve', v));
    if (mode === FLOCK) this.buildRanges(doc);
    this.buildFields(doc);
    if (mode === FLOCK) this.buildFuzzy(doc);
  }

  buildRanges(doc) {
    const folder = this.folder('Boids and limits (ranges)');
    for (const [key, def, min, max] of RANGES) {
      const r = this.value(doc, key) ?? def, pair = { lo: r[0], hi: r[1] };
      const send = () => this.setScoped(key, [pair.lo, pair.hi]);
      folder.add(pair, 'lo', min, max).name(`${key.replace('shape_flock.', '')} lo`).onChange(send);
      folder.add(pair, 'hi', min, max).name(`${key.replace('shape_flock.', '')} hi`).onChange(send);
    }
  }

  // Each style field's gain and scale where it has them (the fields' own keys: scene.md). A group
  // that flies the top level's fields gets its own list, the whole of it, at its first edit (a
  // list's elements cannot be set one by one where the group has no list).
  buildFields(doc) {
    const fields = this.value(doc, 'style.fields') ?? [];
    if (!fields.length) return;
    const folder = this.folder('Style fields');
    const own = this.group < 0 || getKey(doc.groups[this.group], 'style.fields') !== undefined;
    const draft = structuredClone(fields);
    fields.forEach((f, i) => {
      for (const k of ['gain', 'scale', 'speed', 'strength']) {
        if (typeof f[k] !== 'number') continue;
        const key = `style.fields.${i}.${k}`, holder = { [key]: f[k] };
        folder.add(holder, key, 0, Math.max(10, 4 * f[k])).name(`${i} ${f.type} ${k}`).onChange((v) => {
          draft[i][k] = v;
          if (own) this.setScoped(key, v); else this.setScoped('style.fields', structuredClone(draft));
        });
      }
    });
  }

  // The fuzzy curves' key points as JSON text ([[d, w], ...]); empty goes back to the default.
  buildFuzzy(doc) {
    const folder = this.folder('Fuzzy curves [[d, w], ...]');
    for (const name of FUZZY) {
      const key = `shape_flock.fuzzy.${name}`, holder = { [key]: JSON.stringify(this.value(doc, key) ?? '') };
      folder.add(holder, key).name(name).onFinishChange((text) => {
        if (!text.trim() || text === '""') return this.setScoped(key, null);
        try { this.setScoped(key, JSON.parse(text)); } catch (e) { this.app.showError(`${key}: not JSON: ${e.message}`); }
      });
    }
  }

  // Another tab's edit (or the loader's rounding): the controls show the scene as it is now.
  refresh(doc) {
    for (const key of Object.keys(this.values)) {
      const v = this.value(doc, key);
      if (v !== undefined) this.values[key] = v;
    }
    this.gui.controllersRecursive().forEach((c) => c.updateDisplay());
  }
}
