// The page: every panel of registry.js in its place, and one Connection; each time it is connected, every panel
// is given the new RosSession, and on loss it is taken back. Panels hold no connection of their own (see
// connection.js). Nothing runs until start().
import { readAddress, keepInAddress } from './address.js';
import { Connection, bridgeUrl } from './connection.js';
import { PANELS, viewersFor } from './registry.js';
import { Feedback } from './parts/feedback.js';
import { linkReport } from './panels/link.js';

const TAB_PARAM = 'tab';  // ?tab=services: the console's tab shown

export function start() {
  // What the panels share (each is given it): the feedback list, the panels by name (made in the registry's
  // order: a panel may use those before it at once, any of them later), and the viewers of a message type.
  const page = { feedback: new Feedback(), panels: new Map(), viewersFor };
  for (const row of PANELS) page.panels.set(row.name, new row.Panel(placeFor(row), page));
  startTabs(page.panels);

  const url = bridgeUrl();
  const onSession = session => {
    for (const panel of page.panels.values()) {
      if (session) panel.attach(session);
      else panel.detach();
    }
    // (what a slow link cost is counted in the link's health strip, not written here once a second)
    session?.onStatus(status => status.level === 'error' && !linkReport(status) &&
      page.feedback.add(`Bridge: ${status.msg}`, 'error'));
  };
  new Connection(url, { onState: connectionShown(url, page.feedback), onSession }).start();
}

// A panel's element, empty, in its place: in the page's header bar, in the world's card, a card of its own beside
// the world (headed by its title), or a console tab (its button named by its title).
function placeFor({ name, title, place }) {
  const root = document.createElement(place === 'console' ? 'div' : 'section');
  if (place === 'bar') {
    root.id = name;
    root.setAttribute('aria-label', title);
    document.getElementById('conn').before(root);
  } else if (place === 'world') {
    root.setAttribute('aria-label', title);
    document.querySelector('.layout .world').append(root);
  } else if (place === 'side') {
    root.className = 'card';
    root.setAttribute('aria-labelledby', `${name}-title`);
    root.innerHTML = `<h2 id="${name}-title"></h2>`;
    root.firstChild.textContent = title;
    document.querySelector('.layout .side').append(root);
  } else {
    const button = document.createElement('button');
    Object.assign(button, { id: `tab-button-${name}`, type: 'button', textContent: title });
    button.setAttribute('role', 'tab');
    button.setAttribute('aria-controls', `tab-${name}`);
    document.querySelector('.console .tabs').append(button);
    root.id = `tab-${name}`;
    root.setAttribute('role', 'tabpanel');
    root.setAttribute('aria-labelledby', button.id);
    document.querySelector('.console').append(root);
  }
  return root;
}

// The console shows one tab at a time, the one the address asks for at first; the others are shown once, now.
function startTabs(panels) {
  const tabs = PANELS.filter(row => row.place === 'console').map(row => row.name);
  const show = chosen => {
    for (const name of tabs) {
      const shown = name === chosen;
      document.getElementById(`tab-${name}`).hidden = !shown;
      document.getElementById(`tab-button-${name}`).setAttribute('aria-selected', String(shown));
      panels.get(name).show(shown);
    }
  };
  for (const name of tabs) {
    document.getElementById(`tab-button-${name}`).addEventListener('click', () => {
      show(name);
      keepInAddress(TAB_PARAM, [name]);
    });
  }
  const [asked] = readAddress(TAB_PARAM);
  show(tabs.includes(asked) ? asked : tabs[0]);
  for (const [name, panel] of panels) {
    if (!tabs.includes(name)) panel.show(true);
  }
}

// The connection's state in the header's badge, and each change of it in the feedback list.
function connectionShown(url, feedback) {
  let lastState = null;
  return (state, detail) => {
    const seconds = typeof detail === 'number' ? ` · retrying in ${(detail / 1000).toFixed(1)} s` : '';
    const text = {
      connecting: 'Connecting…',
      connected: 'Connected',
      closed: `Closed${seconds}`,
      error: `No bridge${seconds}`,
    }[state];
    document.getElementById('conn').dataset.state = state;
    document.getElementById('conn-text').textContent = text;
    document.body.classList.toggle('offline', state !== 'connected');
    if (state === lastState) return;  // one line per change, not one per retry
    lastState = state;
    const line = {
      connecting: [`Connecting to ${url}`, 'info'],
      connected: [`Connection to ${url} opened.`, 'ok'],
      closed: ['Connection to the bridge closed; reconnecting by itself.', 'error'],
      error: [`Connection to ${url} failed; retrying.`, 'error'],
    }[state];
    feedback.add(...line);
  };
}
