// Nodes (rosnode list / info): every node; choosing one shows what it publishes, subscribes to and provides.
import { ListPanel, fillSelect } from '../parts/panel.js';

export class NodesPanel extends ListPanel {
  constructor(root, page) {
    super(root, page, 'Could not list nodes');
    root.innerHTML = `
      <p class="hint">rosnode list · info. <span class="node-count muted"></span></p>
      <p class="panel-status error" role="status"></p>
      <label for="node-name" class="sr-only">Node</label><select id="node-name" class="node-name"></select>
      <div class="node-details"></div>`;
    this.select = root.querySelector('select.node-name');
    this.count = root.querySelector('.node-count');
    this.details = root.querySelector('.node-details');
    this.select.addEventListener('change', () => this.showNode(this.select.value));
  }

  async load(session) {
    return (await session.rosapi('nodes')).nodes;
  }

  render(nodes) {
    this.count.textContent = `(${nodes.length})`;
    fillSelect(this.select, 'Choose a node…', nodes.map(n => [n, n]));
    if (this.select.value) this.showNode(this.select.value);
  }

  async showNode(node) {
    if (!node || !this.session) {
      this.details.replaceChildren();
      return;
    }
    try {
      const info = await this.session.rosapi('node_details', { node });
      if (this.select.value !== node) return;
      this.details.replaceChildren(...[['Publications', info.publishing], ['Subscriptions', info.subscribing],
        ['Services', info.services]].map(([title, names]) => {
        const block = document.createElement('section');
        block.innerHTML = '<h3></h3><ul class="names"></ul>';
        block.firstChild.textContent = `${title} (${names.length})`;
        block.lastChild.replaceChildren(...[...names].sort().map(n => {
          const item = document.createElement('li');
          item.innerHTML = '<code></code>';
          item.firstChild.textContent = n;
          return item;
        }));
        return block;
      }));
    } catch (error) {
      this.status.textContent = `Could not read ${node}: ${error.message}`;
    }
  }
}
