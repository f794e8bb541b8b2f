// The control page: wires the bridge connection to the world view, the drive controls, the
// tutorial panel, the service buttons and the topic list.
import { Connection, bridgeUrl } from './connection.js';
import { WorldView, WORLD_M } from './world.js';
import { Driver } from './drive.js';

const DISCOVERY_MS = 2000;  // how often the topic list (and so the set of turtles) is refreshed
const $ = id => document.getElementById(id);

const view = new WorldView($('world'));
window.turtleView = view.debugHook();

let ros = null;  // a connected ROSLIB.Ros, or null
let poseTopics = new Map();  // turtle name -> subscribed ROSLIB.Topic
let cmdVel = null;  // {name, topic} advertised on the current connection
let discoveryTimer = null;

// ---- numbers typed by people -------------------------------------------------------------------

// Accepts "1.5", "-2", ".5", "1e-3" and a decimal comma ("1,5", what phone keypads in many locales
// type); anything else is an inline error on the field. Returns the number, null for a blank
// optional field, or undefined when invalid.
function readNumber(input, { optional = false } = {}) {
  const text = input.value.trim().replace(',', '.');
  let error = '';
  if (text === '') {
    if (!optional) error = 'Enter a number.';
  } else if (!/^[+-]?(\d+\.?\d*|\.\d+)(e[+-]?\d+)?$/i.test(text) || !Number.isFinite(Number(text))) {
    error = `“${input.value.trim()}” is not a number.`;
  }
  showFieldError(input, error);
  if (error) return undefined;
  return text === '' ? null : Number(text);
}

function showFieldError(input, message) {
  const out = $(`${input.id}-err`);
  out.textContent = message;
  out.hidden = !message;
  input.toggleAttribute('aria-invalid', Boolean(message));
}

// Reads several fields at once (so every bad one is marked); undefined if any is invalid.
function readNumbers(ids, options) {
  const values = ids.map(id => readNumber($(id), options));
  return values.includes(undefined) ? undefined : values;
}

// ---- feedback ----------------------------------------------------------------------------------

function feedback(text, kind = 'info') {
  const list = $('feedback');
  const item = document.createElement('li');
  item.className = kind;
  const time = new Date().toLocaleTimeString([], { hour12: false });
  item.innerHTML = '<time></time> <span></span>';
  item.firstChild.textContent = time;
  item.lastChild.textContent = text;
  list.prepend(item);
  while (list.children.length > 6) list.lastChild.remove();
}

function serviceStatus(text, kind = 'info') {
  const out = $('service-status');
  out.textContent = text;
  out.className = `status ${kind}`;
}

// ---- connection --------------------------------------------------------------------------------

const url = bridgeUrl();
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
  feedback(...log);
}

function onOpen(connected) {
  ros = connected;
  ros.on('status', status => status.level === 'error' && feedback(`Bridge: ${status.msg}`, 'error'));
  commandTopic();
  refreshTopics();
  discoveryTimer = setInterval(refreshTopics, DISCOVERY_MS);
}

function onLost() {
  ros = null;
  cmdVel = null;
  poseTopics = new Map();  // their subscriptions died with the socket
  clearInterval(discoveryTimer);
  view.breakTrails();
  driver.stop();  // nothing can be sent now; the turtle stops 1 s after its last command
}

// ---- discovery: the topic list and the turtles ------------------------------------------------

function refreshTopics() {
  if (!ros) return;
  const asked = ros;
  asked.getTopics(({ topics, types }) => {
    if (asked !== ros) return;
    const entries = topics.map((name, i) => [name, types[i]]).sort(([a], [b]) => a.localeCompare(b));
    showTopics(entries);
    trackTurtles(entries.filter(([name, type]) => type === 'turtlesim/Pose' && /^\/[^/]+\/pose$/.test(name))
      .map(([name]) => name.split('/')[1]));
  }, error => feedback(`Could not list topics: ${error}`, 'error'));
}

let shownTopics = '';

function showTopics(entries) {
  const list = $('topics');
  const key = JSON.stringify(entries);
  if (key === shownTopics) return;  // leave a selection or a scroll position alone
  shownTopics = key;
  list.replaceChildren(...entries.map(([name, type]) => {
    const item = document.createElement('li');
    item.innerHTML = '<code class="name"></code><code class="type"></code>';
    item.firstChild.textContent = name;
    item.lastChild.textContent = type;
    return item;
  }));
  $('topics-count').textContent = `(${entries.length})`;
}

function trackTurtles(names) {
  for (const [name, topic] of poseTopics) {
    if (names.includes(name)) continue;
    topic.unsubscribe();
    poseTopics.delete(name);
  }
  for (const name of view.names) {
    if (!names.includes(name)) view.remove(name);
  }
  for (const name of names) {
    if (poseTopics.has(name)) continue;
    const topic = new ROSLIB.Topic({ ros, name: `/${name}/pose`, messageType: 'turtlesim/Pose' });
    topic.subscribe(pose => view.setPose(name, pose));
    poseTopics.set(name, topic);
  }
  showTargets(names);
}

function showTargets(names) {
  const select = $('target');
  const current = select.value;
  const wanted = names.length ? [...names].sort() : [current];
  if ([...select.options].map(o => o.value).join() === wanted.join()) return;
  select.replaceChildren(...wanted.map(name => new Option(name, name)));
  select.value = wanted.includes(current) ? current : wanted[0];
  if (select.value !== current) switchTarget();
}

function target() {
  return $('target').value || 'turtle1';
}

function showTarget() {
  $('cmd-vel-name').textContent = `/${target()}/cmd_vel`;
  for (const el of document.querySelectorAll('.target-name')) el.textContent = target();
}

// ---- publishing Twists -------------------------------------------------------------------------

// The cmd_vel publisher of the driven turtle, advertised ahead of the first command (on connect and on
// a change of turtle) so that turtlesim is already subscribed when the first Twist goes out.
function commandTopic() {
  const name = `/${target()}/cmd_vel`;
  if (cmdVel?.name !== name) {
    cmdVel?.topic.unadvertise();
    cmdVel = { name, topic: new ROSLIB.Topic({ ros, name, messageType: 'geometry_msgs/Twist', queue_size: 1 }) };
    cmdVel.topic.advertise();
  }
  return cmdVel.topic;
}

// Never queued while disconnected: a stale command must not move the turtle after a reconnect.
function publishTwist(linear, angular) {
  if (!ros) return false;
  (cmdVel?.topic ?? commandTopic()).publish(new ROSLIB.Message({
    linear: { x: linear, y: 0, z: 0 },
    angular: { x: 0, y: 0, z: angular },
  }));
  return true;
}

function tutorialSpeeds() {
  const values = readNumbers(['linear', 'angular']);
  return values && { linear: values[0], angular: values[1] };
}

$('twist-form').addEventListener('submit', e => {
  e.preventDefault();
  const speeds = tutorialSpeeds();
  if (!speeds) {
    feedback('Nothing published: fix the highlighted number.', 'error');
    return;
  }
  if (publishTwist(speeds.linear, speeds.angular)) {
    feedback(`Published linear.x = ${speeds.linear}, angular.z = ${speeds.angular} on /${target()}/cmd_vel.`, 'ok');
  } else {
    feedback('Nothing published: not connected to the bridge.', 'error');
  }
});

const driver = new Driver({
  publish: publishTwist,
  // Full stick = the tutorial speeds' magnitudes; the keys give the direction.
  speeds: () => {
    const speeds = tutorialSpeeds();
    return speeds && { linear: Math.abs(speeds.linear), angular: Math.abs(speeds.angular) };
  },
  joystick: $('joystick'),
});

// The driven turtle is stopped first: its zero Twist still goes to the publisher of the old name.
function switchTarget() {
  driver.stop();
  showTarget();
  if (ros) commandTopic();
}

$('target').addEventListener('change', switchTarget);

// ---- services ----------------------------------------------------------------------------------

function callService(name, type, args, done) {
  if (!ros) {
    serviceStatus(`Not connected: ${name} was not called.`, 'error');
    return;
  }
  serviceStatus(`Calling ${name}…`);
  const service = new ROSLIB.Service({ ros, name, serviceType: type });
  service.callService(new ROSLIB.ServiceRequest(args), result => {
    serviceStatus(done(result), 'ok');
    refreshTopics();
  }, error => serviceStatus(`${name} failed: ${error || 'the service reported an error'}`, 'error'));
}

$('clear').addEventListener('click', () => callService('/clear', 'std_srvs/Empty', {}, () => {
  view.clearTrails();
  return 'Trails cleared.';
}));

$('reset').addEventListener('click', () => callService('/reset', 'std_srvs/Empty', {}, () => {
  view.forgetTurtles();
  return 'World reset: turtle1 is back in the centre.';
}));

$('spawn-form').addEventListener('submit', e => {
  e.preventDefault();
  const values = readNumbers(['spawn-x', 'spawn-y', 'spawn-theta'], { optional: true });
  if (!values) return;
  const margin = 1;  // keep random turtles off the walls
  const random = (lo, hi) => lo + Math.random() * (hi - lo);
  const [x, y, theta] = values;
  const args = {
    x: x ?? random(margin, WORLD_M - margin),
    y: y ?? random(margin, WORLD_M - margin),
    theta: theta ?? random(-Math.PI, Math.PI),
    name: $('spawn-name').value.trim(),
  };
  callService('/spawn', 'turtlesim/Spawn', args,
    result => `Spawned ${result.name} at (${args.x.toFixed(2)}, ${args.y.toFixed(2)}).`);
});

$('teleport-form').addEventListener('submit', e => {
  e.preventDefault();
  const values = readNumbers(['tp-x', 'tp-y', 'tp-theta']);
  if (!values) return;
  const [x, y, theta] = values;
  const name = target();
  callService(`/${name}/teleport_absolute`, 'turtlesim/TeleportAbsolute', { x, y, theta },
    () => `Teleported ${name} to (${x}, ${y}, ${theta}).`);
});

new Connection(url, { onState, onOpen, onLost }).start();
