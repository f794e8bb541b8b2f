// What every console panel shares: it is given the connected RosSession (attach) and loses it (detach), and it
// refreshes what it lists when shown. A subclass says what to list (load(session), resolving to plain data) and
// how to show it (render(data)); a list that did not change is left alone, with a choice or a scroll in it.
export class Panel {
  constructor(root, failure) {
    this.root = root;
    this.failure = failure;  // e.g. 'Could not list nodes'
    this.status = root.querySelector('.panel-status');
    this.session = null;
    this.shown = null;
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
      const data = await this.load(session);
      if (session !== this.session) return;
      this.status.textContent = '';
      const key = JSON.stringify(data);
      if (key === this.shown) return;
      this.shown = key;
      this.render(data);
    } catch (error) {
      this.status.textContent = `${this.failure}: ${error.message}`;
    }
  }
}

// Fills a <select> with a placeholder and [value, label] choices, keeping the current choice if it is still there.
export function fillSelect(select, placeholder, choices) {
  const chosen = select.value;
  select.replaceChildren(new Option(placeholder, ''), ...choices.map(([value, label]) => new Option(label, value)));
  select.value = choices.some(([value]) => value === chosen) ? chosen : '';
}

// Shows a ROS name in an element so that a narrow screen breaks it after a '/' (a <wbr>, which copying leaves out).
export function showName(element, name) {
  const parts = name.split(/(?<=\/)/);
  element.replaceChildren(...parts.flatMap((part, i) => (i ? [document.createElement('wbr'), part] : [part])));
}
