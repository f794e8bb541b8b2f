// The page: one Connection; each time it is connected, every panel is given the new RosSession, and on loss it
// is taken back. Panels hold no connection of their own (see connection.js).
import { readAddress, keepInAddress } from './address.js';
import { Connection, bridgeUrl } from './connection.js';
import * as turtle from './panels/turtle.js';
import { TopicsPanel } from './panels/topics.js';
import { PublishPanel } from './panels/publish.js';
import { ServicesPanel } from './panels/services.js';
import { ParamsPanel } from './panels/params.js';
import { NodesPanel } from './panels/nodes.js';
import { CameraPanel } from './panels/camera.js';
import { LogsPanel } from './panels/logs.js';

const $ = id => document.getElementById(id);
const url = bridgeUrl();

// The console's tabs, in the order of the tutorial's terminal windows.
const panels = {
  topics: new TopicsPanel($('tab-topics')),
  publish: new PublishPanel($('tab-publish')),
  services: new ServicesPanel($('tab-services')),
  params: new ParamsPanel($('tab-params')),
  nodes: new NodesPanel($('tab-nodes')),
  camera: new CameraPanel($('tab-camera')),
  logs: new LogsPanel($('tab-logs')),
};

function showTab(name) {
  for (const [key, panel] of Object.entries(panels)) {
    const shown = key === name;
    $(`tab-${key}`).hidden = !shown;
    $(`tab-button-${key}`).setAttribute('aria-selected', String(shown));
    panel.show(shown);
  }
}

for (const name of Object.keys(panels)) {
  $(`tab-button-${name}`).addEventListener('click', () => {
    showTab(name);
    keepInAddress('tab', [name]);
  });
}
const [asked] = readAddress('tab');
showTab(Object.hasOwn(panels, asked) ? asked : 'topics');

let lastState = null;

function onState(state, detail) {
  const seconds = typeof detail === 'number' ? ` · retrying in ${(detail / 1000).toFixed(1)} s` : '';
  const text = {
    connecting: 'Connecting…',
    connected: 'Connected',
    closed: `Closed${seconds}`,
    error: `No bridge${seconds}`,
  }[state];
  $('conn').dataset.state = state;
  $('conn-text').textContent = text;
  document.body.classList.toggle('offline', state !== 'connected');
  if (state === lastState) return;  // one line per change, not one per retry
  lastState = state;
  const log = {
    connecting: [`Connecting to ${url}`, 'info'],
    connected: [`Connection to ${url} opened.`, 'ok'],
    closed: ['Connection to the bridge closed; reconnecting by itself.', 'error'],
    error: [`Connection to ${url} failed; retrying.`, 'error'],
  }[state];
  turtle.feedback(...log);
}

function onSession(session) {
  for (const panel of [turtle, ...Object.values(panels)]) {
    if (session) panel.attach(session);
    else panel.detach();
  }
}

new Connection(url, { onState, onSession }).start();
