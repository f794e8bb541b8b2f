// The page's feedback list: connection and publish events, newest first, the last few kept. app.js writes the
// connection's changes to it, the drive panels what became of their Twists; the Twist form shows it.
const KEPT = 6;

export class Feedback {
  constructor() {
    this.element = document.createElement('ol');
    this.element.id = 'feedback';
    this.element.className = 'feedback';
    this.element.setAttribute('role', 'log');
    this.element.setAttribute('aria-live', 'polite');
    this.element.setAttribute('aria-label', 'Connection and publish feedback');
  }

  add(text, kind = 'info') {
    const list = this.element;
    if (list.firstChild?.lastChild.textContent === text) list.firstChild.remove();  // (e.g. every drive command refused)
    const item = document.createElement('li');
    item.className = kind;
    item.innerHTML = '<time></time> <span></span>';
    item.firstChild.textContent = new Date().toLocaleTimeString([], { hour12: false });
    item.lastChild.textContent = text;
    list.prepend(item);
    while (list.children.length > KEPT) list.lastChild.remove();
  }
}
