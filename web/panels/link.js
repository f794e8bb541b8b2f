// The link's health, in a strip of the page's header: the round trip to the bridge (a /rosapi/get_time call timed
// every 2 s; one still unanswered shows how long it has waited), the bytes per second received (websocket messages
// and picture streams as the page reads them: approximate), and the messages the bridge skipped or dropped for
// this page (its `status` reports: "skipped N older message(s)" when a slow link made it keep only the newest of
// a topic, "dropped N ..." or "refused N ..." for real losses), counted since the page was opened.
import { Panel } from '../parts/panel.js';
import { formatAge, formatBytes } from '../format.js';

const PING_MS = 2000;
const TICK_MS = 1000;
const TITLES = {
  rtt: 'Round trip to the bridge: a /rosapi/get_time call, timed every 2 s',
  rate: "Bytes per second received: the sizes of the websocket's messages and of the picture streams' bodies as " +
    "the page reads them, without the network's own overhead (approximate)",
  skipped: 'Messages the bridge skipped for this page since it was opened (a slow link: it kept only the newest ' +
    'of a topic), and messages lost',
};

// What a bridge's status message reports of this page's link: { skipped, lost } (message counts), or null when it
// is about something else.
export function linkReport({ level, msg }) {
  const match = /^(skipped|dropped|refused) (\d+) /.exec(typeof msg === 'string' ? msg : '');
  if (!match) return null;
  const count = Number(match[2]);
  if (match[1] === 'skipped' && level === 'warning') return { skipped: count, lost: 0 };
  return match[1] === 'skipped' ? null : { skipped: 0, lost: count };
}

export class LinkPanel extends Panel {
  constructor(root, page) {
    super(root, page);
    root.classList.add('link-health');
    root.innerHTML = '<span class="rtt">RTT <b>—</b></span> <span class="rate">↓ <b>—</b></span> ' +
      '<span class="skipped"><b>0</b> skipped</span>';
    for (const [name, title] of Object.entries(TITLES)) root.querySelector(`.${name}`).title = title;
    this.parts = Object.fromEntries(['rtt', 'rate', 'skipped'].map(name => [name, root.querySelector(`.${name} b`)]));
    this.skippedText = root.querySelector('.skipped');
    this.skipped = 0;
    this.lost = 0;
    this.timers = [];
  }

  attach(session) {
    super.attach(session);
    this.waiting = null;  // when the unanswered ping was sent (performance.now ms)
    this.counted = [performance.now(), session.received];
    session.onStatus(status => this.count(status));
    this.timers = [setInterval(() => this.ping(), PING_MS), setInterval(() => this.tick(), TICK_MS)];
    this.ping();
  }

  detach() {
    super.detach();
    for (const timer of this.timers) clearInterval(timer);
    this.parts.rtt.textContent = '—';
    this.parts.rate.textContent = '—';
  }

  count(status) {
    const report = linkReport(status);
    if (!report) return;
    this.skipped += report.skipped;
    this.lost += report.lost;
    this.parts.skipped.textContent = String(this.skipped);
    this.skippedText.lastChild.textContent = this.lost ? ` skipped · ${this.lost} lost` : ' skipped';
    this.skippedText.classList.toggle('bad', this.lost > 0);
  }

  async ping() {
    const session = this.session;
    if (!session || this.waiting !== null) return;  // (one at a time: tick() shows how long one waits)
    this.waiting = performance.now();
    try {
      const seconds = await session.ping();
      if (session === this.session) this.parts.rtt.textContent = formatAge(seconds);
    } catch {
      if (session === this.session) this.parts.rtt.textContent = 'no answer';
    } finally {
      if (session === this.session) this.waiting = null;
    }
  }

  tick() {
    const session = this.session;
    const now = performance.now();
    const [then, received] = this.counted;
    this.counted = [now, session.received];
    this.root.dataset.received = String(session.received);  // (the bytes so far, for whoever measures the page)
    this.parts.rate.textContent = `${formatBytes((session.received - received) / ((now - then) / 1000))}/s`;
    if (this.waiting !== null && now - this.waiting > PING_MS) {
      this.parts.rtt.textContent = `> ${formatAge((now - this.waiting) / 1000)}`;
    }
  }
}
