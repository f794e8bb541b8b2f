// Nodes (rosnode list / info): every node; choosing one shows what it publishes, subscribes to and provides.
export class NodesPanel {
  constructor(root) {
    this.root = root;
    this.select = root.querySelector('select.node-name');
    this.count = root.querySelector('.node-count');
    this.details = root.querySelector('.node-details');
    this.status = root.querySelector('.panel-status');
    this.session = null;
    this.select.addEventListener('change', () => this.showNode(this.select.value));
  }

  attach(session) {
    this.session = session;
    this.refresh();
  }

  detach() {
    this.session = null;
  }

  show(visible) {
    if (visible) this.refresh();
  }

  async refresh() {
    const session = this.session;
    if (!session) return;
    try {
      const { nodes } = await session.rosapi('nodes');
      if (session !== this.session) return;
      const chosen = this.select.value;
      this.status.textContent = '';
      if (JSON.stringify(nodes) === this.shown) return;  // unchanged: leave the choice alone
      this.shown = JSON.stringify(nodes);
      this.count.textContent = `(${nodes.length})`;
      this.select.replaceChildren(new Option('Choose a node…', ''), ...nodes.map(n => new Option(n, n)));
      this.select.value = nodes.includes(chosen) ? chosen : '';
      if (this.select.value) this.showNode(this.select.value);
      this.status.textContent = '';
    } catch (error) {
      this.status.textContent = `Could not list nodes: ${error.message}`;
    }
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
