// The transforms of /tf and /tf_static (tf2_msgs/TFMessage), one store per RosSession, shared by every viewer that
// uses TF (viewers/tf.js, viewers/map.js): TfStore.use(session) subscribes once for all of them and returns the
// store with a release() (the last release unsubscribes). Per frame: its parent, its newest transform to it, static
// or not, its header stamp, and when its transforms arrived (the rate over the last RATE_WINDOW_S).
import { IDENTITY, compose, invert, transformOf } from './tf-math.js';

const RATE_WINDOW_S = 5;
const MAX_ARRIVALS = 2000;  // per frame, in the window (a 1 kHz frame's rate reads as a floor beyond this)
const stores = new WeakMap();  // session -> TfStore

export class TfStore {
  static use(session) {
    let store = stores.get(session);
    if (!store || store.closed) {
      store = new TfStore(session);
      stores.set(session, store);
    }
    store.users++;
    let released = false;
    return {
      store,
      release: () => {
        if (released) return;
        released = true;
        if (--store.users === 0) store.close();
      },
    };
  }

  constructor(session) {
    this.session = session;
    this.users = 0;
    this.closed = false;
    this.frames = new Map();  // child -> { parent, transform, isStatic, stamp (s or null), arrivals: [ms] }
    this.version = 0;  // counts the messages taken (a viewer redraws when it changed)
    this.listeners = new Set();
    if (session) {
      this.subscriptions = [['/tf', false], ['/tf_static', true]].map(([topic, isStatic]) =>
        session.subscribe(topic, 'tf2_msgs/TFMessage', message => this.take(message, isStatic)));
    } else {
      this.subscriptions = [];
    }
  }

  // listener() after each message taken; returns a function that removes it.
  listen(listener) {
    this.listeners.add(listener);
    return () => this.listeners.delete(listener);
  }

  take(message, isStatic, now = performance.now()) {
    for (const stamped of message.transforms ?? []) {
      const child = trimFrame(stamped.child_frame_id);
      const parent = trimFrame(stamped.header?.frame_id);
      if (!child || !parent || child === parent) continue;
      let frame = this.frames.get(child);
      if (!frame) {
        frame = { arrivals: [] };
        this.frames.set(child, frame);
      }
      const stamp = stamped.header?.stamp;
      Object.assign(frame, { parent, isStatic, transform: transformOf(stamped.transform),
        stamp: stamp ? stamp.secs + stamp.nsecs / 1e9 : null, arrived: now });
      if (!isStatic) {
        frame.arrivals.push(now);
        if (frame.arrivals.length > MAX_ARRIVALS) frame.arrivals.shift();
      }
    }
    this.version++;
    for (const listener of this.listeners) listener();
  }

  // Transforms per second of a frame over the last RATE_WINDOW_S (0 for a static one).
  rate(child, now = performance.now()) {
    const frame = this.frames.get(child);
    if (!frame) return 0;
    const arrivals = frame.arrivals;
    while (arrivals.length && arrivals[0] < now - RATE_WINDOW_S * 1000) arrivals.shift();
    if (arrivals.length < 2) return 0;
    return (arrivals.length - 1) / Math.max((now - arrivals[0]) / 1000, 1e-3);
  }

  // Every frame named, parents and roots included, sorted (numbers in names by value).
  names() {
    const names = new Set(this.frames.keys());
    for (const frame of this.frames.values()) names.add(frame.parent);
    return [...names].sort((a, b) => a.localeCompare(b, 'en', { numeric: true }));  // (fast_2 before fast_10)
  }

  // The chain of frames from `name` up to its root: [name, parent, ..., root] (cycles cut).
  chain(name) {
    const chain = [name];
    const seen = new Set(chain);
    for (let frame = this.frames.get(name); frame && !seen.has(frame.parent); frame = this.frames.get(frame.parent)) {
      chain.push(frame.parent);
      seen.add(frame.parent);
    }
    return chain;
  }

  // The transform root <- name along its chain.
  toRoot(name) {
    let transform = IDENTITY;
    const chain = this.chain(name);
    for (let i = chain.length - 2; i >= 0; i--) transform = compose(transform, this.frames.get(chain[i]).transform);
    return { root: chain.at(-1), transform };
  }

  // The transform target <- source (maps a point in source's coordinates to target's), by the newest transforms,
  // or null when they are not in one tree.
  lookup(target, source) {
    const a = this.toRoot(target);
    const b = this.toRoot(source);
    if (a.root !== b.root) return null;
    return compose(invert(a.transform), b.transform);
  }

  // Frames below `ancestor` (its tree, by the parents known), itself excluded.
  descendants(ancestor) {
    return [...this.frames.keys()].filter(name => name !== ancestor && this.chain(name).includes(ancestor));
  }

  close() {
    this.closed = true;
    for (const subscription of this.subscriptions) subscription.close();
    this.listeners.clear();
  }
}

// tf2 names frames without a leading slash (tf1's "/base_link" is "base_link").
export function trimFrame(name) {
  return typeof name === 'string' ? name.replace(/^\/+/, '') : '';
}
