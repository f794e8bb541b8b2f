// The one shape of a panel. app.js makes each panel from its row in registry.js, with the element it lives in
// (empty: the panel fills it) and the page's shared parts (app.js says which); then it hands the panel each
// connected RosSession (attach) and takes it back when the socket goes (detach), and tells a console tab when it
// is shown or hidden (show; the panels outside the console are shown once, at start). A panel that keeps a view
// in the page's address (address.js) reads its key in its constructor and writes it when the person changes it.
// Nothing happens when a panel's module is imported: the panel starts in its constructor.
export class Panel {
  constructor(root, page) {
    this.root = root;
    this.page = page;
    this.session = null;
  }

  attach(session) {
    this.session = session;
  }

  detach() {
    this.session = null;
  }

  show() {}
}

// A panel that lists something and refreshes it when shown. A subclass says what to list (load(session),
// resolving to plain data) and how to show it (render(data)); a list that did not change is left alone, with a
// choice or a scroll in it. Failures go to the panel's `.panel-status` line.
export class ListPanel extends Panel {
  constructor(root, page, failure) {
    super(root, page);
    this.failure = failure;  // e.g. 'Could not list nodes'
    this.shown = null;
  }

  get status() {
    return this.root.querySelector('.panel-status');
  }

  attach(session) {
    super.attach(session);
    this.refresh();
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
