// TF (/tf, /tf_static: tf2_msgs/TFMessage): the frame tree, each frame with its parent, its rate (or "static", a
// /tf_static frame; "root"), the age of its newest transform (by its header stamp); and the transform between any two frames
// chosen (composed along the tree by ../tf-math.js: translation, quaternion, roll/pitch/yaw). The transforms come
// from ../tf-store.js, shared with the map viewer: this viewer needs no messages of the topic opened.
import { TfStore } from '../tf-store.js';
import { rpyOf } from '../tf-math.js';
import { formatAge } from '../format.js';

const REFRESH_MS = 250;  // the table is written again this often (ages change): not at the topic's 100 Hz

export class TfViewer {
  // (No `subscription`: the store subscribes /tf unthrottled for the rates, and the bridge merges a client's
  // subscriptions of one topic at the lowest throttle_rate, so asking less here would change nothing.)

  constructor(element) {
    element.innerHTML = `
      <div class="tf-viewer">
        <div class="tf-pick row">
          <label>From <select class="tf-source" aria-label="Source frame"></select></label>
          <label>to <select class="tf-target" aria-label="Target frame"></select></label>
        </div>
        <p class="tf-transform" aria-live="off">Choose two frames.</p>
        <div class="scroll"><table class="tf-frames">
          <thead><tr><th>Frame</th><th>Parent</th><th class="num">Rate</th><th class="num">Age</th></tr></thead>
          <tbody></tbody></table></div>
        <p class="tf-count muted"></p>
      </div>`;
    this.$ = selector => element.querySelector(selector);
    this.sourceSelect = this.$('.tf-source');
    this.targetSelect = this.$('.tf-target');
    for (const select of [this.sourceSelect, this.targetSelect]) select.addEventListener('change', () => this.refresh());
    this.held = null;  // { store, release }
    this.session = null;
    this.names = '';  // the frame names the selects offer, joined
    this.timer = setInterval(() => this.refresh(), REFRESH_MS);
  }

  get store() {
    return this.held?.store ?? null;
  }

  attach(session) {
    this.detach();
    this.session = session;
    this.held = TfStore.use(session);
  }

  detach() {
    this.held?.release();
    this.held = null;
    this.session = null;
  }

  draw() {}  // (the store has the messages)

  refresh() {
    const store = this.store;
    if (!store) return;
    const now = performance.now();
    const names = store.names();
    if (names.join('\n') !== this.names) {
      this.names = names.join('\n');
      this.offer(this.sourceSelect, names, names.find(n => !store.frames.has(n)) ?? names[0]);
      this.offer(this.targetSelect, names, names.find(n => store.frames.has(n) && !store.frames.get(n).isStatic)
        ?? names.at(-1));
    }
    const rows = treeOrder(store, names).map(({ name, depth }) => {
      const frame = store.frames.get(name);
      // the rate column says static (a /tf_static frame) or root (a frame nobody's child) instead of a rate
      const rate = !frame ? 'root' : frame.isStatic ? 'static' : `${store.rate(name, now).toFixed(1)} Hz`;
      const age = frame?.isStatic || !frame ? '' : frame.stamp ? formatAge(this.session.ageOf(frame.stamp)) : '—';
      return [name, depth, frame?.parent ?? '', rate, age];
    });
    const body = this.$('.tf-frames tbody');
    while (body.rows.length > rows.length) body.deleteRow(-1);
    while (body.rows.length < rows.length) {
      const row = body.insertRow();
      row.innerHTML = '<td class="frame"></td><td class="parent"></td><td class="num rate"></td><td class="num age"></td>';
    }
    rows.forEach(([name, depth, parent, rate, age], i) => {
      const row = body.rows[i];
      row.dataset.frame = name;
      const texts = [`${' '.repeat(2 * Math.max(0, depth - 1))}${depth ? '└ ' : ''}${name}`, parent, rate, age];
      texts.forEach((text, j) => {
        if (row.cells[j].textContent !== text) row.cells[j].textContent = text;
      });
    });
    const dynamic = [...store.frames.values()].filter(f => !f.isStatic).length;
    this.$('.tf-count').textContent = `${names.length} frames · ${dynamic} dynamic · ` +
      `${store.frames.size - dynamic} static`;
    this.showTransform(store);
  }

  offer(select, names, fallback) {
    const chosen = select.value || fallback;
    select.replaceChildren(...names.map(name => new Option(name, name)));
    select.value = names.includes(chosen) ? chosen : fallback;
  }

  showTransform(store) {
    const [source, target] = [this.sourceSelect.value, this.targetSelect.value];
    const element = this.$('.tf-transform');
    if (!source || !target) return;
    const found = store.lookup(target, source);
    let text;
    if (!found) text = `${source} and ${target} are not in one tree.`;
    else {
      const { translation: t, rotation: q } = found;
      const { roll, pitch, yaw } = rpyOf(q);
      const f = v => (Math.abs(v) < 5e-7 ? 0 : v).toFixed(3);
      const deg = v => f(v * 180 / Math.PI);
      text = `${target} ← ${source}: translation (${f(t.x)}, ${f(t.y)}, ${f(t.z)}) m · ` +
        `rotation (${f(q.x)}, ${f(q.y)}, ${f(q.z)}, ${f(q.w)}) · roll ${deg(roll)}° pitch ${deg(pitch)}° ` +
        `yaw ${deg(yaw)}°`;
      element.dataset.transform = JSON.stringify(found);
    }
    if (element.textContent !== text) element.textContent = text;
  }

  close() {
    clearInterval(this.timer);
    this.detach();
  }
}

// The frames depth first from each root, children sorted by name: [{ name, depth }].
function treeOrder(store, names) {
  const children = new Map();
  for (const name of names) {
    const parent = store.frames.get(name)?.parent;
    if (parent === undefined) continue;
    if (!children.has(parent)) children.set(parent, []);
    children.get(parent).push(name);
  }
  const order = [];
  const seen = new Set();
  const visit = (name, depth) => {
    if (seen.has(name)) return;
    seen.add(name);
    order.push({ name, depth });
    for (const child of children.get(name) ?? []) visit(child, depth + 1);
  };
  for (const name of names) if (!store.frames.has(name)) visit(name, 0);  // roots
  for (const name of names) visit(name, 0);  // (frames in a cycle)
  return order;
}
