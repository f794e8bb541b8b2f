// Topics (rostopic list / info / echo / hz / bw, rosmsg show): the list with types, publisher and subscriber
// counts; an opened topic shows its info, its definition and its latest message as a live tree (pausable),
// with its rate and bandwidth and the age of its newest message, and offers the viewers of its type
// (registry.js) beside the tree; one whose messages may be big shows its definition instead, until a viewer is
// chosen (OpenTopic). Several can be open; closing one unsubscribes.
//
// A message is shown at the next animation frame after it arrives (the newest, if several came in between), and
// only its changed values are written when its shape is the tree's.
import { readAddress, keepInAddress } from '../address.js';
import { formatAge, formatBytes } from '../format.js';
import { bulkArrays, definitionText, messageTree, treeShape } from '../parts/messages.js';
import { ListPanel, showName } from '../parts/panel.js';
import { Plot } from '../parts/plot.js';

const REFRESH_MS = 3000;
const WINDOW_S = 5;  // rate and bandwidth over the last seconds, as rostopic hz/bw's window
const FAST_HZ = 200;  // above this the bridge throttles what it sends this page (the rate shown is then a floor)
const THROTTLE_MS = 50;
const FAST_SAMPLES = 50;  // arrivals needed before a topic is judged fast (messages also arrive in bursts)
const TICK_MS = 250;  // the newest message's age is shown again this often
const STATS_EVERY = 4;  // ticks between two showings of the rate and bandwidth
const INFO_EVERY = 12;  // ticks between two askings of who publishes and subscribes
const TREE_MAX_BYTES = 1e6;  // a bigger message stops the tree's subscription (a viewer's is not bounded)
const ONE_MESSAGE = { compression: 'cbor', queue_length: 1 };  // one fetched on request: its arrays as bytes
const TOPIC_PARAM = 'topic';  // ?topic=/turtle1/pose&topic=/odom: the open topics, kept in the page's address
const VIEW_PARAM = 'view';  // ?view=/turtle1/pose:turtle: the viewers shown in them

export class TopicsPanel extends ListPanel {
  constructor(root, page) {
    super(root, page, 'Could not list topics');
    root.innerHTML = `
      <p class="hint">rostopic list · info · echo · hz · bw, and rosmsg show: open a topic to watch it.
        <span class="topic-count muted"></span></p>
      <p class="panel-status error" role="status"></p>
      <section class="plot" hidden aria-label="Plot of the chosen fields"></section>
      <div class="open-topics"></div>
      <div class="scroll"><table class="topic-list">
        <thead><tr><th>Topic</th><th>Type</th><th class="num">Pubs</th><th class="num">Subs</th><th class="num">Rate</th>
        </tr></thead>
        <tbody></tbody>
      </table></div>`;
    this.list = root.querySelector('.topic-list tbody');
    this.count = root.querySelector('.topic-count');
    this.openArea = root.querySelector('.open-topics');
    this.plot = new Plot(root.querySelector('.plot'));
    this.visible = false;
    this.open = new Map();  // topic name -> OpenTopic (kept across reconnections)
    this.wanted = readAddress(TOPIC_PARAM);  // topics of the address not listed yet: opened once they are
    this.views = new Map(readAddress(VIEW_PARAM).map(kept => kept.split(':')));  // topic -> its viewer shown
    this.timer = null;
  }

  attach(session) {
    super.attach(session);
    for (const topic of this.open.values()) topic.attach(session);
    this.timer = setInterval(() => this.visible && this.refresh(), REFRESH_MS);
  }

  detach() {
    super.detach();
    clearInterval(this.timer);
    for (const topic of this.open.values()) topic.detach();
  }

  show(visible) {
    this.visible = visible;
    for (const topic of this.open.values()) topic.show(visible);
    super.show(visible);
  }

  // [[name, type, publishers, subscribers, rate]], rates of the open topics included (they change too)
  async load(session) {
    const { topics, types } = await session.rosapi('topics');
    return Promise.all(topics.map(async (name, i) => [name, types[i],
      ...(await Promise.all([
        session.rosapi('publishers', { topic: name }).then(r => r.publishers.length, () => '?'),
        session.rosapi('subscribers', { topic: name }).then(r => r.subscribers.length, () => '?')])),
      this.open.get(name)?.rateText() ?? '']))
      .then(rows => rows.sort(([a], [b]) => a.localeCompare(b)));
  }

  render(rows) {
    this.count.textContent = `(${rows.length})`;
    this.list.replaceChildren(...rows.map(([name, type, pubs, subs, rate]) => {
      const row = document.createElement('tr');
      row.dataset.topic = name;
      row.innerHTML = '<td><button type="button" class="link"></button></td><td><code></code></td>' +
        '<td class="num"></td><td class="num"></td><td class="num rate"></td>';
      const cells = row.children;
      showName(cells[0].firstChild, name);
      cells[0].firstChild.addEventListener('click', () => this.openTopic(name, type));
      showName(cells[1].firstChild, type);
      [cells[2].textContent, cells[3].textContent, cells[4].textContent] = [String(pubs), String(subs), rate];
      return row;
    }));
    const types = new Map(rows.map(([name, type]) => [name, type]));
    for (const name of this.wanted.filter(n => types.has(n))) this.openTopic(name, types.get(name));
  }

  openTopic(name, type) {
    if (this.open.has(name)) {
      this.open.get(name).element.scrollIntoView({ block: 'nearest' });
      return;
    }
    const viewers = this.page.viewersFor(type);
    const topic = new OpenTopic(name, type, this.plot, viewers, {
      shown: viewers.find(viewer => viewer.name === this.views.get(name)),
      onView: viewer => {
        if (viewer) this.views.set(name, viewer.name);
        else this.views.delete(name);
        this.keepInAddress();
      },
      onClose: () => {
        this.open.delete(name);
        this.views.delete(name);
        topic.element.remove();
        this.keepInAddress();
      },
    });
    this.open.set(name, topic);
    topic.show(this.visible);
    this.wanted = this.wanted.filter(n => n !== name);
    this.openArea.prepend(topic.element);
    if (this.session) topic.attach(this.session);
    this.keepInAddress();
  }

  keepInAddress() {
    keepInAddress(TOPIC_PARAM, [...this.open.keys(), ...this.wanted]);
    keepInAddress(VIEW_PARAM, [...this.views].map(([topic, viewer]) => `${topic}:${viewer}`));
  }
}

// One opened topic. viewers: the registry's rows for its type, offered as buttons; shown: the one to show at
// once, if any; onView(row or null) when the person shows or hides one; onClose() when closed.
//
// Its tree follows the topic unless its messages may be big: a type with a variable-length array of bytes (an
// image's, a map's or a cloud's data: megabytes, which no client can ask the bridge for in part) is not
// subscribed to until a viewer is chosen, and a message that turns out bigger than TREE_MAX_BYTES stops the
// tree's subscription. Such a topic shows its definition instead, and fetches one message (binary) on request.
class OpenTopic {
  constructor(name, type, plot, viewers, { shown, onView, onClose }) {
    this.name = name;
    this.plot = plot;
    this.type = type;
    this.viewers = viewers;
    this.paused = false;
    this.arrivals = [];  // [time s, bytes]: of the messages, or of what the viewer drew (drawing)
    this.latest = null;
    this.openBranches = new Set();
    this.subscription = null;
    this.throttled = false;
    this.throttle = null;  // the throttle_rate asked of the bridge (ms), if any
    this.session = null;
    this.viewer = null;  // {row, viewer}: the viewer shown
    this.visible = false;  // its tab is shown
    this.frame = null;  // the animation frame that will show the newest message
    this.drawn = null;  // the message the tree shows
    this.tree = null;  // { shape, leaves: the value elements }: what the tree shows, to change in place
    this.newest = null;  // { arrived (ms), age at arrival (s, from its stamp) or null, noun (of a drawing) }
    this.bulk = null;  // the definition's arrays of bytes (bulkArrays), once read this session
    this.tooBig = 0;  // the size of a message that stopped the tree's subscription (bytes)
    this.fetching = false;  // one message asked for, not followed
    this.fetched = '';  // what the stats say of it
    this.drawing = null;  // { noun, via } once the viewer says what it draws (it fetches it itself: onDrawn)
    this.element = document.createElement('article');
    this.element.className = 'open-topic';
    this.element.dataset.topic = name;
    this.element.innerHTML = `
      <header><h3><code class="name"></code> <small class="type"></small></h3>
        <div class="buttons"><button type="button" class="pause">Pause</button>
          <button type="button" class="close" aria-label="Close">Close</button></div></header>
      <div class="viewer" hidden></div>
      <div class="topic-text">
        <p class="stats" aria-live="off">waiting for a message…</p>
        <p class="age" aria-live="off"></p>
        <div class="summary" hidden><p></p>
          <button type="button" class="fetch">Fetch one message</button></div>
        <p class="info muted"></p>
        <details class="definition"><summary>Definition <small>(rosmsg show)</small></summary><pre></pre></details>
        <div class="message"></div>
      </div>`;
    // its parts, found before a viewer is put in (whose own elements may have the same classes)
    this.$ = Object.fromEntries(['name', 'type', 'pause', 'close', 'viewer', 'stats', 'age', 'summary', 'fetch', 'info',
      'definition', 'message'].map(part => [part, this.element.querySelector(`.${part}`)]));
    this.$.name.textContent = name;
    this.$.type.textContent = type;
    this.$.pause.before(...viewers.map(row => {
      const button = document.createElement('button');
      button.type = 'button';
      button.className = 'view';
      button.dataset.viewer = row.name;
      button.textContent = row.title;
      button.title = `Show the ${row.title.toLowerCase()} view`;
      button.setAttribute('aria-pressed', 'false');
      button.addEventListener('click', () => {
        const showing = this.viewer?.row === row;
        this.showViewer(showing ? null : row);
        onView(showing ? null : row);
      });
      return button;
    }));
    if (shown) this.showViewer(shown);
    this.$.pause.addEventListener('click', () => this.togglePause());
    this.$.fetch.addEventListener('click', () => this.fetchOne());
    // on the container, at pointerdown: the tree is redrawn several times a second, so a leaf may be replaced
    // between a press and its release
    this.$.message.addEventListener('pointerdown', event => {
      const leaf = event.target.closest('li.plottable');
      if (leaf) this.plot.add(this.name, JSON.parse(leaf.dataset.path));
    });
    this.$.close.addEventListener('click', () => {
      this.detach();
      this.viewer?.viewer.close();
      onClose();
    });
    this.ticks = 0;
    this.statsTimer = setInterval(() => this.tick(), TICK_MS);
  }

  attach(session) {
    this.session = session;
    this.bulk = null;
    this.viewer?.viewer.attach?.(session);
    if (this.viewer) this.subscribe();  // (a viewer's messages need no definition; the tree's wait for it)
    this.readDefinition(session);
    this.showInfo();
  }

  show(visible) {
    this.visible = visible;
    if (visible) this.scheduleRender();
  }

  // The definition (rosmsg show), which also says whether the tree may follow the topic; then the tree's
  // subscription, unless a viewer's is there already.
  async readDefinition(session) {
    let typedefs = [];
    try {
      ({ typedefs } = await session.rosapi('message_details', { type: this.type }));
    } catch (error) {
      if (session === this.session) this.$.info.textContent = `Could not read the type: ${error.message}`;
    }
    if (session !== this.session) return;
    this.$.definition.querySelector('pre').textContent = definitionText(typedefs);
    this.bulk = bulkArrays(typedefs);
    if (!this.viewer) this.subscribe();
  }

  // Who publishes and subscribes changes (this page's own subscription appears a moment after opening).
  async showInfo() {
    const session = this.session;
    if (!session) return;
    try {
      const [pubs, subs] = await Promise.all([session.rosapi('publishers', { topic: this.name }),
        session.rosapi('subscribers', { topic: this.name })]);
      if (session !== this.session) return;
      this.$.info.textContent = `Publishers: ${pubs.publishers.join(', ') || 'none'} · ` +
        `Subscribers: ${subs.subscribers.join(', ') || 'none'}`;
    } catch (error) {
      this.$.info.textContent = `Could not read the topic's details: ${error.message}`;
    }
  }

  // Shows a viewer (one at a time) beside the tree, or none (null). What it asks of the subscription (e.g. binary
  // images) applies while it is shown.
  showViewer(row) {
    this.viewer?.viewer.close();
    this.viewer = null;
    const area = this.$.viewer;
    area.replaceChildren();
    area.hidden = !row;
    this.element.classList.toggle('with-viewer', Boolean(row));
    if (row) {
      this.fetching = false;  // (the viewer's messages come instead)
      this.fetched = '';
      const onChange = () => this.session && this.subscribe();
      let made = null;
      const onDrawn = drawn => this.viewer?.viewer === made && this.countDrawn(drawn);
      made = new row.Viewer(area, { topic: this.name, type: this.type, onChange, onDrawn });
      this.viewer = { row, viewer: made };
      if (this.session) made.attach?.(this.session);
    }
    for (const button of this.element.querySelectorAll('button.view')) {
      button.setAttribute('aria-pressed', String(button.dataset.viewer === row?.name));
    }
    if (this.session) this.subscribe();
  }

  // Why the tree does not follow the topic: a text, '' when it does, null while its definition is unknown.
  notFollowed() {
    if (this.viewer) return '';
    if (this.bulk === null) return null;
    if (this.bulk.length) return `a ${this.type} may be megabytes (${this.bulk.join(', ')})`;
    return this.tooBig ? `its messages are ${formatBytes(this.tooBig)}` : '';
  }

  subscribe() {
    this.subscription?.close();
    this.subscription = null;
    this.drawing = null;
    const why = this.notFollowed();
    this.showSummary(why);
    if (why === null || (why && !this.fetching)) return;
    const viewer = this.viewer;
    const options = why ? ONE_MESSAGE : { ...(this.throttled ? { throttle_rate: THROTTLE_MS, queue_length: 1 } : {}),
      ...(viewer && ('subscription' in viewer.viewer ? viewer.viewer.subscription : viewer.row.Viewer.subscription)) };
    if ((options.throttle_rate ?? null) !== this.throttle) this.arrivals = [];  // (another rate to measure)
    this.throttle = options.throttle_rate ?? null;
    this.subscription = this.session.subscribe(this.name, this.type, message => this.receive(message), options);
  }

  // Instead of a tree that follows the topic: why, the definition opened, and one message on request.
  showSummary(why) {
    const summary = this.$.summary;
    const definition = this.$.definition;
    if (!why && !summary.hidden) definition.open = false;  // (opened for the summary; the tree takes its place)
    summary.hidden = !why;
    if (!why) return;
    definition.open = true;
    const titles = this.viewers.map(row => row.title).join(', ');
    summary.firstChild.textContent = `Not followed: ${why}. ${titles ? `Choose a viewer (${titles}) to watch it, or ` +
      'fetch' : 'Fetch'} one message for its tree.`;
    this.showStats();
  }

  fetchOne() {
    if (!this.session || this.fetching || !this.notFollowed()) return;
    this.fetching = true;
    this.fetched = 'fetching one message…';
    this.subscribe();
  }

  detach() {
    this.subscription?.close();
    this.subscription = null;
    this.viewer?.viewer.detach?.();
    this.session = null;
  }

  receive(message) {
    const now = performance.now();
    const size = sizeOf(message);
    if (!this.drawing) {
      this.arrivals.push([now / 1000, size]);
      this.forgetOld(now);
      const stamp = message.header?.stamp;
      this.newest = { arrived: now, age: stamp ? this.session?.ageOf(stamp) ?? null : null };
    }
    if (this.latest === null) {  // the first: subscribed by now (this page is among the subscribers), and the
      this.showInfo();           // stats no longer say "waiting" while the age already shows
      if (this.visible) this.showStats();
    }
    this.latest = message;
    this.plot.push(this.name, message);
    if (!this.paused) this.viewer?.viewer.draw(message);
    if (this.fetching && !this.viewer) {  // the one asked for
      this.fetching = false;
      this.fetched = `one message fetched on request: ${formatBytes(size)}`;
      this.subscribe();
    } else if (!this.viewer && size > TREE_MAX_BYTES) {
      this.tooBig = size;
      this.fetched = '';
      this.subscribe();
    } else if (!this.throttled && this.arrivals.length >= FAST_SAMPLES && this.hz() > FAST_HZ) {  // too fast
      this.throttled = true;
      this.subscribe();
    }
    this.scheduleRender();
  }

  // Something the viewer drew that it fetched itself (e.g. a cloud by /cloud, a picture by its stream): the rate,
  // bandwidth and age shown are the drawing's, not those of the tree's messages (which then come seldom).
  countDrawn({ stamp, bytes, noun, via }) {
    const now = performance.now();
    if (!this.drawing) this.arrivals = [];
    this.drawing = { noun, via };
    this.arrivals.push([now / 1000, bytes]);
    this.forgetOld(now);
    this.newest = { arrived: now, age: stamp ? this.session?.ageOf(stamp) ?? null : null, noun };
  }

  forgetOld(now) {
    while (this.arrivals.length && this.arrivals[0][0] < now / 1000 - WINDOW_S) this.arrivals.shift();
  }

  // The newest message is shown at the next animation frame (one per frame, and none while its tab is hidden).
  scheduleRender() {
    if (this.paused || !this.visible || this.frame !== null || this.latest === this.drawn) return;
    this.frame = requestAnimationFrame(() => {
      this.frame = null;
      if (this.visible && this.element.isConnected) this.render();
    });
  }

  hz() {
    const a = this.arrivals;
    if (a.length < 2) return 0;
    return (a.length - 1) / Math.max(a[a.length - 1][0] - a[0][0], 1e-6);
  }

  rateText() {
    if (this.arrivals.length < 2 || this.notFollowed()) return '';
    return `${this.throttle && !this.drawing ? '≥ ' : ''}${this.hz().toFixed(1)} Hz`;
  }

  tick() {
    if (!this.element.isConnected) {
      clearInterval(this.statsTimer);
      return;
    }
    this.ticks++;
    if (this.ticks % INFO_EVERY === 0) this.showInfo();
    if (this.visible) this.showAge();
    if (this.visible && this.ticks % STATS_EVERY === 0) this.showStats();
  }

  // How old the newest message (or drawing) is now: by its stamp (the bridge's clock, RosSession.ageOf) when it
  // has one, else since it arrived.
  showAge() {
    const newest = this.newest;
    if (!newest) return;
    const since = (performance.now() - newest.arrived) / 1000;
    const what = newest.noun ? `newest ${newest.noun} drawn` : 'newest message';
    const stamp = newest.noun ? 'stamp' : 'header.stamp';  // (a drawing's: its header's, else when the bridge got it)
    const text = newest.age === null ? `${what}: ${formatAge(since)} since it arrived (it has no ${stamp})`
      : `${what}: ${formatAge(newest.age + since)} old (by its ${stamp})`;
    const element = this.$.age;
    if (element.textContent !== text) element.textContent = text;
  }

  showStats() {
    const stats = this.$.stats;
    if (this.notFollowed()) {
      stats.textContent = this.fetched;
      return;
    }
    const a = this.arrivals;
    if (!a.length) return;
    const seconds = Math.max(performance.now() / 1000 - a[0][0], 1e-3);
    const bytes = a.reduce((sum, [, size]) => sum + size, 0);
    const drawing = this.drawing;
    const why = this.throttled ? 'fast topic: ' : this.viewer ? `for the ${this.viewer.row.title.toLowerCase()} ` +
      'view: ' : '';
    const note = drawing ? ` (the ${drawing.noun}s drawn, ${drawing.via}; the tree's messages: one every ` +
      `${this.throttle} ms)` : this.throttle ? ` (${why}the bridge sends this page one every ${this.throttle} ms)` : '';
    const bandwidth = a.length < 2 ? '—' : `${formatBytes(bytes / seconds)}/s`;  // (not one message's bytes in 1 ms)
    stats.textContent = `average rate: ${this.rateText() || '—'} · bandwidth: ${bandwidth} · ` +
      `${a.length} ${drawing ? `${drawing.noun}s` : 'messages'} in the last ${WINDOW_S} s${note}`;
  }

  togglePause() {
    this.paused = !this.paused;
    this.$.pause.textContent = this.paused ? 'Resume' : 'Pause';
    if (!this.paused) this.render();
  }

  render() {
    if (this.latest === null || this.paused) return;
    const message = this.latest;
    this.drawn = message;
    const { shape, texts } = treeShape(message);
    if (this.tree?.shape === shape) {  // the same fields: only the values that changed are written
      texts.forEach((text, i) => {
        const leaf = this.tree.leaves[i];
        if (leaf.textContent !== text) leaf.textContent = text;
      });
    } else {
      const leaves = [];
      this.$.message.replaceChildren(messageTree(message, {
        open: this.openBranches,
        leaves,
        onLeaf: (path, item, value) => {
          if (typeof value !== 'number') return;
          item.classList.add('plottable');
          item.title = 'Plot it';
          item.dataset.path = JSON.stringify(path);
        },
      }));
      this.tree = { shape, leaves };
    }
    if (!this.$.age.textContent) this.showAge();  // (then every TICK_MS, not at every frame)
  }
}

// About the bytes a message took: its JSON text, binary arrays (CBOR, for a viewer) at their size.
function sizeOf(message) {
  let binary = 0;
  const text = JSON.stringify(message, (key, value) => {
    if (!ArrayBuffer.isView(value)) return value;
    binary += value.byteLength;
    return 0;
  });
  return text.length + binary;
}

