// Logs (rqt_console): every node's log lines from /rosout_agg as they come, filtered by level, node and text;
// the newest first, at most HISTORY kept.
import { Panel } from '../parts/panel.js';

const HISTORY = 1000;
const LEVELS = { 1: 'DEBUG', 2: 'INFO', 4: 'WARN', 8: 'ERROR', 16: 'FATAL' };

export class LogsPanel extends Panel {
  constructor(root, page) {
    super(root, page);
    root.innerHTML = `
      <p class="hint">Every node's log (/rosout_agg), newest first. <span class="log-count muted"></span></p>
      <div class="row log-filters">
        <label>Level <select class="log-level">
          <option value="1">debug and up</option><option value="2" selected>info and up</option>
          <option value="4">warnings and up</option><option value="8">errors and up</option></select></label>
        <label>Node <select class="log-node"><option value="">every node</option></select></label>
        <label>Text <input class="log-search" type="search" autocomplete="off" placeholder="search"></label>
        <button type="button" class="log-clear">Clear</button>
      </div>
      <ol class="log-lines" aria-live="off"></ol>`;
    this.list = root.querySelector('.log-lines');
    this.level = root.querySelector('select.log-level');
    this.node = root.querySelector('select.log-node');
    this.search = root.querySelector('input.log-search');
    this.count = root.querySelector('.log-count');
    this.lines = [];
    this.nodes = new Set();
    this.subscription = null;
    // (a select chosen by script or assistive tools may fire only 'change')
    for (const control of [this.level, this.node, this.search]) {
      for (const event of ['input', 'change']) control.addEventListener(event, () => this.render());
    }
    root.querySelector('button.log-clear').addEventListener('click', () => {
      this.lines = [];
      this.render();
    });
  }

  attach(session) {
    super.attach(session);
    this.subscription = session.subscribe('/rosout_agg', 'rosgraph_msgs/Log', line => this.receive(line));
  }

  detach() {
    super.detach();
    this.subscription = null;  // (gone with the socket)
  }

  receive(line) {
    this.lines.unshift(line);
    if (this.lines.length > HISTORY) this.lines.pop();
    if (!this.nodes.has(line.name)) {
      this.nodes.add(line.name);
      const chosen = this.node.value;
      this.node.replaceChildren(new Option('every node', ''), ...[...this.nodes].sort().map(n => new Option(n, n)));
      this.node.value = chosen;
    }
    clearTimeout(this.renderTimer);
    this.renderTimer = setTimeout(() => this.render(), 100);  // a burst of lines: one redraw
  }

  render() {
    const least = Number(this.level.value);
    const node = this.node.value;
    const text = this.search.value.trim().toLowerCase();
    const shown = this.lines.filter(l => l.level >= least && (!node || l.name === node)
      && (!text || l.msg.toLowerCase().includes(text)));
    this.count.textContent = `(${shown.length} of ${this.lines.length})`;
    this.list.replaceChildren(...shown.slice(0, 200).map(line => {
      const item = document.createElement('li');
      item.className = `level-${LEVELS[line.level] ?? 'INFO'}`;
      item.innerHTML = '<span class="lvl"></span> <time></time> <code class="node"></code> <span class="msg"></span>';
      const [level, time, name, msg] = item.children;
      level.textContent = LEVELS[line.level] ?? line.level;
      time.textContent = new Date(line.header.stamp.secs * 1000).toLocaleTimeString([], { hour12: false });
      name.textContent = line.name;
      msg.textContent = line.msg;
      return item;
    }));
  }
}
