// Topics (rostopic list / info / echo / hz / bw, rosmsg show): the list with types, publisher and subscriber
// counts; an opened topic shows its info, its definition and its latest message as a live tree (pausable),
// with its rate and bandwidth, and offers the viewers of its type (registry.js) beside the tree. Several can be
// open; closing one unsubscribes.
import { readAddress, keepInAddress } from '../address.js';
import { definitionText, messageTree } from './messages.js';
import { ListPanel, showName } from './panel.js';
import { Plot } from './plot.js';

const REFRESH_MS = 3000;
const WINDOW_S = 5;  // rate and bandwidth over the last seconds, as rostopic hz/bw's window
const FAST_HZ = 200;  // above this the bridge throttles what it sends this page (the rate shown is then a floor)
const THROTTLE_MS = 50;
const FAST_SAMPLES = 50;  // arrivals needed before a topic is judged fast (messages also arrive in bursts)
const RENDER_MS = 150;
const INFO_EVERY_S = 3;  // the tree is redrawn at most this often, whatever the topic's rate
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
class OpenTopic {
  constructor(name, type, plot, viewers, { shown, onView, onClose }) {
    this.name = name;
    this.plot = plot;
    this.type = type;
    this.paused = false;
    this.arrivals = [];  // [time s, bytes]
    this.latest = null;
    this.openBranches = new Set();
    this.subscription = null;
    this.throttled = false;
    this.session = null;
    this.viewer = null;  // {row, viewer}: the viewer shown
    this.element = document.createElement('article');
    this.element.className = 'open-topic';
    this.element.dataset.topic = name;
    this.element.innerHTML = `
      <header><h3><code class="name"></code> <small class="type"></small></h3>
        <div class="buttons"><button type="button" class="pause">Pause</button>
          <button type="button" class="close" aria-label="Close">Close</button></div></header>
      <p class="stats" aria-live="off">waiting for a message…</p>
      <p class="info muted"></p>
      <details class="definition"><summary>Definition <small>(rosmsg show)</small></summary><pre></pre></details>
      <div class="viewer" hidden></div>
      <div class="message"></div>`;
    this.$ = selector => this.element.querySelector(selector);
    this.$('.name').textContent = name;
    this.$('.type').textContent = type;
    this.$('.pause').before(...viewers.map(row => {
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
    this.$('.pause').addEventListener('click', () => this.togglePause());
    // on the container, at pointerdown: the tree is redrawn several times a second, so a leaf may be replaced
    // between a press and its release
    this.$('.message').addEventListener('pointerdown', event => {
      const leaf = event.target.closest('li.plottable');
      if (leaf) this.plot.add(this.name, JSON.parse(leaf.dataset.path));
    });
    this.$('.close').addEventListener('click', () => {
      this.detach();
      this.viewer?.viewer.close();
      onClose();
    });
    this.ticks = 0;
    this.statsTimer = setInterval(() => this.showStats(), 1000);
  }

  attach(session) {
    this.session = session;
    this.subscribe();
    this.showInfo();
  }

  // Who publishes and subscribes changes (this page's own subscription appears a moment after opening).
  async showInfo() {
    const session = this.session;
    if (!session) return;
    try {
      const [pubs, subs, details] = await Promise.all([
        session.rosapi('publishers', { topic: this.name }), session.rosapi('subscribers', { topic: this.name }),
        session.rosapi('message_details', { type: this.type })]);
      this.$('.info').textContent = `Publishers: ${pubs.publishers.join(', ') || 'none'} · ` +
        `Subscribers: ${subs.subscribers.join(', ') || 'none'}`;
      if (session !== this.session) return;
      this.$('.definition pre').textContent = definitionText(details.typedefs);
    } catch (error) {
      this.$('.info').textContent = `Could not read the topic's details: ${error.message}`;
    }
  }

  // Shows a viewer (one at a time) beside the tree, or none (null). What it asks of the subscription (e.g. binary
  // images) applies while it is shown.
  showViewer(row) {
    this.viewer?.viewer.close();
    this.viewer = null;
    const area = this.$('.viewer');
    area.replaceChildren();
    area.hidden = !row;
    if (row) this.viewer = { row, viewer: new row.Viewer(area, { topic: this.name, type: this.type }) };
    for (const button of this.element.querySelectorAll('button.view')) {
      button.setAttribute('aria-pressed', String(button.dataset.viewer === row?.name));
    }
    if (this.session) this.subscribe();
  }

  subscribe() {
    this.subscription?.close();
    const options = { ...(this.throttled ? { throttle_rate: THROTTLE_MS, queue_length: 1 } : {}),
      ...this.viewer?.row.Viewer.subscription };
    this.subscription = this.session.subscribe(this.name, this.type, message => this.receive(message), options);
  }

  detach() {
    this.subscription?.close();
    this.subscription = null;
    this.session = null;
    clearTimeout(this.renderTimer);
    this.renderTimer = null;
  }

  receive(message) {
    const now = performance.now() / 1000;
    this.arrivals.push([now, sizeOf(message)]);
    while (this.arrivals.length && this.arrivals[0][0] < now - WINDOW_S) this.arrivals.shift();
    if (this.latest === null) this.showInfo();  // subscribed by now: this page is among the subscribers
    this.latest = message;
    this.plot.push(this.name, message);
    if (!this.paused) this.viewer?.viewer.draw(message);
    if (!this.throttled && this.arrivals.length >= FAST_SAMPLES && this.hz() > FAST_HZ) {  // too fast to show
      this.throttled = true;
      this.subscribe();
    }
    if (!this.paused && !this.renderTimer) {
      this.renderTimer = setTimeout(() => {
        this.renderTimer = null;
        this.render();
      }, RENDER_MS);
    }
  }

  hz() {
    const a = this.arrivals;
    if (a.length < 2) return 0;
    return (a.length - 1) / Math.max(a[a.length - 1][0] - a[0][0], 1e-6);
  }

  rateText() {
    if (this.arrivals.length < 2) return '';
    return `${this.throttled ? '≥ ' : ''}${this.hz().toFixed(1)} Hz`;
  }

  showStats() {
    if (!this.element.isConnected) {
      clearInterval(this.statsTimer);
      return;
    }
    if (++this.ticks % INFO_EVERY_S === 0) this.showInfo();
    const a = this.arrivals;
    if (!a.length) return;
    const seconds = Math.max(performance.now() / 1000 - a[0][0], 1e-3);
    const bytes = a.reduce((sum, [, size]) => sum + size, 0);
    const note = this.throttled ? ` (fast topic: the bridge sends this page one every ${THROTTLE_MS} ms)` : '';
    this.$('.stats').textContent = `average rate: ${this.rateText() || '—'} · bandwidth: ` +
      `${formatBytes(bytes / seconds)}/s · ${a.length} messages in the last ${WINDOW_S} s${note}`;
  }

  togglePause() {
    this.paused = !this.paused;
    this.$('.pause').textContent = this.paused ? 'Resume' : 'Pause';
    if (!this.paused) this.render();
  }

  render() {
    if (this.latest === null || this.paused) return;
    this.$('.message').replaceChildren(messageTree(this.latest, {
      open: this.openBranches,
      onLeaf: (path, item, value) => {
        if (typeof value !== 'number') return;
        item.classList.add('plottable');
        item.title = 'Plot it';
        item.dataset.path = JSON.stringify(path);
      },
    }));
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

function formatBytes(perSecond) {
  if (perSecond >= 1e6) return `${(perSecond / 1e6).toFixed(2)} MB`;
  if (perSecond >= 1e3) return `${(perSecond / 1e3).toFixed(2)} KB`;
  return `${perSecond.toFixed(0)} B`;
}
