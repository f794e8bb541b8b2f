// Bags (rosbag record, rqt_bag's recorder): the bridge's bag recorder over its HTTP API (/bags, see the README's
// Bags): choose topics, record and stop, or keep them in the black box (the last minute, in the bridge's memory)
// and save it; the folder's bags with their size and date, downloaded by a plain link, deleted after a question.
// The topics chosen are kept in the address (?bag=/turtle1/pose&bag=/rosout).
import { readAddress, keepInAddress } from '../address.js';
import { confirmFirst } from '../parts/confirm.js';
import { Panel, showName } from '../parts/panel.js';

const BAG_PARAM = 'bag';
const POLL_MS = 1000;

export class BagsPanel extends Panel {
  constructor(root, page) {
    super(root, page);
    root.innerHTML = `
      <p class="hint">rosbag record on the robot: choose topics, record or keep them in the black box, download the
        bags. <span class="bag-used muted"></span></p>
      <p class="panel-status error" role="status"></p>
      <div class="bag-off" hidden>
        <p class="error">The bridge's bag recorder is off.</p>
        <p class="muted">Start the bridge with a folder for the bags:
          <code>roslaunch turtlesim rosbridge_websocket.launch bag_folder:=$HOME/bags</code>
          (<code>bash tools/demo</code> turns it on).</p>
      </div>
      <div class="bag-tools">
        <div class="bag-topics" role="group" aria-labelledby="bag-topics-title">
          <p id="bag-topics-title" class="bag-topics-title">Topics <span class="bag-chosen muted"></span></p>
          <input class="bag-filter" type="search" placeholder="Filter topics" aria-label="Filter topics"
            autocomplete="off" spellcheck="false">
          <div class="bag-topic-list"></div>
        </div>
        <div class="bag-record">
          <div class="row"><button type="button" class="bag-start primary">Record</button>
            <button type="button" class="bag-stop stop" hidden>Stop</button>
            <span class="bag-recording" role="status" aria-live="polite"></span></div>
          <p class="bag-last"></p>
          <div class="row"><button type="button" class="blackbox-keep">Keep in the black box</button>
            <button type="button" class="blackbox-off" hidden>Black box off</button>
            <button type="button" class="blackbox-save" hidden>Save the black box</button>
            <span class="blackbox-state muted" role="status"></span></div>
          <p class="bag-result" role="status" aria-live="polite"></p>
        </div>
      </div>
      <div class="scroll"><table class="bag-list"><thead><tr><th>Bag</th><th>Size</th><th>Date</th><th></th></tr>
        </thead><tbody></tbody></table></div>`;
    this.$ = selector => root.querySelector(selector);
    this.chosen = new Set(readAddress(BAG_PARAM));
    this.topics = [];  // [name, type] of the graph
    this.timer = null;
    this.visible = false;
    this.state = null;
    this.$('.bag-start').addEventListener('click', () => this.act('record', { topics: [...this.chosen] }));
    this.$('.bag-stop').addEventListener('click', () => this.act('stop', {}));
    this.$('.blackbox-keep').addEventListener('click', () => this.act('blackbox', { topics: [...this.chosen] }));
    this.$('.blackbox-off').addEventListener('click', () => this.act('blackbox', { topics: [] }));
    this.$('.blackbox-save').addEventListener('click', () => this.act('blackbox/save', {}, 'Black box saved'));
    this.$('.bag-filter').addEventListener('input', () => this.renderTopics());
    this.renderTopics();  // (the topics chosen, before the graph's are known)
    this.renderChosen();
  }

  attach(session) {
    super.attach(session);
    this.poll();
  }

  detach() {
    super.detach();
    clearTimeout(this.timer);
  }

  show(visible) {
    this.visible = visible;
    if (visible) this.poll();
  }

  // While shown: the recorder's state each second, the topic list with it every few.
  async poll() {
    clearTimeout(this.timer);
    const session = this.session;
    if (!session || !this.visible) return;
    if (!this.topicsAt || Date.now() - this.topicsAt > 5000) {
      this.topicsAt = Date.now();
      session.rosapi('topics').then(({ topics, types }) => {
        if (session !== this.session) return;
        const listed = topics.map((name, i) => [name, types[i]]).sort((a, b) => a[0].localeCompare(b[0]));
        if (JSON.stringify(listed) === JSON.stringify(this.topics)) return;
        this.topics = listed;
        this.renderTopics();
      }, () => {});
    }
    try {
      const answer = await fetch(new URL('bags', session.http), { cache: 'no-store' });
      const body = await answer.json().catch(() => ({}));
      if (session !== this.session) return;
      this.$('.panel-status').textContent = '';
      this.$('.bag-off').hidden = answer.status !== 404;
      this.$('.bag-tools').hidden = this.$('.bag-list').hidden = answer.status === 404;
      if (answer.ok) this.render(body);
      else if (answer.status !== 404) this.$('.panel-status').textContent = `Bags: ${body.error || answer.status}`;
    } catch (error) {
      if (session === this.session) this.$('.panel-status').textContent = `Could not ask for the bags: ${error.message}`;
    }
    if (session === this.session) this.timer = setTimeout(() => this.poll(), POLL_MS);
  }

  async request(method, path, body) {
    const answer = await fetch(new URL(path, this.session.http), {
      method, cache: 'no-store',
      ...(body ? { headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) } : {}),
    });
    const reply = await answer.json().catch(() => ({}));
    if (!answer.ok) throw new Error(reply.error || `${answer.status} ${answer.statusText}`);
    return reply;
  }

  async act(action, body, done = '') {
    if (!this.session) return this.say('Not connected.', 'error');
    if ((action === 'record' || (action === 'blackbox' && body.topics.length)) && !this.chosen.size) {
      return this.say('Choose the topics first.', 'error');
    }
    try {
      const state = await this.request('POST', `bags/${action}`, body);
      this.say(done, 'ok');
      this.render(state);
    } catch (error) {
      this.say(error.message, 'error');
    }
  }

  say(text, kind) {
    const line = this.$('.bag-result');
    line.textContent = text;
    line.className = `bag-result ${kind}`;
  }

  renderTopics() {
    const filter = this.$('.bag-filter').value.trim().toLowerCase();
    const names = new Map(this.topics);
    for (const name of this.chosen) if (!names.has(name)) names.set(name, '');  // chosen, not (yet) in the graph
    const rows = [...names].sort((a, b) => a[0].localeCompare(b[0]))
      .filter(([name]) => !filter || this.chosen.has(name) || name.toLowerCase().includes(filter))
      .map(([name, type]) => {
        const label = document.createElement('label');
        label.className = 'bag-topic';
        label.innerHTML = '<input type="checkbox"> <code></code> <small class="muted"></small>';
        const box = label.firstChild;
        box.value = name;
        box.checked = this.chosen.has(name);
        showName(label.querySelector('code'), name);
        label.querySelector('small').textContent = type;
        box.addEventListener('change', () => {
          if (box.checked) this.chosen.add(name);
          else this.chosen.delete(name);
          this.renderChosen();
        });
        return label;
      });
    this.$('.bag-topic-list').replaceChildren(...rows);
  }

  renderChosen() {
    keepInAddress(BAG_PARAM, [...this.chosen].sort());
    this.$('.bag-chosen').textContent = `(${this.chosen.size} chosen)`;
  }

  render(state) {
    this.state = state;
    const { recording, last, blackbox, bags } = state;
    this.$('.bag-used').textContent = `Folder: ${size(state.used_bytes)} of ${size(state.max_bytes)}.`;
    this.$('.bag-start').hidden = Boolean(recording);
    this.$('.bag-stop').hidden = !recording;
    this.$('.bag-recording').textContent = recording
      ? `Recording ${recording.name}: ${((Date.now() / 1000) - recording.started).toFixed(0)} s, ` +
        `${recording.messages} messages, ${size(recording.bytes)}, ${recording.dropped} dropped`
      : '';
    const lastLine = this.$('.bag-last');
    lastLine.textContent = !recording && last
      ? `Last: ${last.name}, ${last.messages} messages, ${size(last.bytes)}, ${last.dropped} dropped` +
        (last.error ? ` — ${last.error}` : '.')
      : '';
    lastLine.className = `bag-last ${last?.error ? 'error' : 'muted'}`;
    this.$('.blackbox-off').hidden = this.$('.blackbox-save').hidden = !blackbox;
    this.$('.blackbox-keep').textContent = blackbox ? 'Black box: the ticked topics instead' : 'Keep in the black box';
    this.$('.blackbox-state').textContent = blackbox
      ? `Black box (${blackbox.topics.join(', ')}): ${blackbox.messages} messages, ${size(blackbox.bytes)} ` +
        `of the last ${blackbox.seconds} s`
      : 'Black box off.';
    const key = JSON.stringify(bags);
    if (key === this.bagsShown) return;  // (a question being asked in the list stays)
    this.bagsShown = key;
    const body = this.$('.bag-list tbody');
    if (!bags.length) {
      body.innerHTML = '<tr><td colspan="4" class="muted">No bags yet.</td></tr>';
      return;
    }
    body.replaceChildren(...bags.map(bag => this.row(bag, recording?.name === bag.name)));
  }

  row(bag, recorded) {
    const row = document.createElement('tr');
    row.dataset.bag = bag.name;
    row.innerHTML = `<td><a class="bag-download" download></a></td><td class="bag-size"></td><td class="bag-date"></td>
      <td class="bag-actions"><button type="button" class="bag-delete">Delete</button></td>`;
    const link = row.querySelector('a');
    link.textContent = bag.name;
    link.href = new URL(`bags/${encodeURIComponent(bag.name)}`, this.session.http).href;
    row.querySelector('.bag-size').textContent = recorded ? `${size(bag.size)} (recording)` : size(bag.size);
    row.querySelector('.bag-date').textContent = new Date(bag.modified * 1000).toLocaleString();
    const remove = row.querySelector('.bag-delete');
    remove.disabled = recorded;
    remove.addEventListener('click', async () => {
      if (!await confirmFirst(remove, `Delete ${bag.name}? This cannot be undone.`, 'Delete')) return;
      try {
        this.render(await this.request('DELETE', `bags/${encodeURIComponent(bag.name)}`));
        this.say(`Deleted ${bag.name}.`, 'ok');
      } catch (error) {
        this.say(`Not deleted: ${error.message}`, 'error');
      }
    });
    return row;
  }
}

function size(bytes) {
  if (bytes == null) return '?';
  if (bytes < 1024) return `${bytes} B`;
  if (bytes < 1024 * 1024) return `${(bytes / 1024).toFixed(1)} kB`;
  if (bytes < 1024 ** 3) return `${(bytes / 1024 / 1024).toFixed(1)} MB`;
  return `${(bytes / 1024 ** 3).toFixed(2)} GB`;
}
