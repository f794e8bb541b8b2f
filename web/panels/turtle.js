// The turtle panel, the first thing one sees: the live world, driving (keys, joystick, the tutorial's Twist
// form), the world's services (clear, reset, spawn, teleport). It holds no connection state of its own
// beyond what the current RosSession gave it, all dropped in detach().
import { WorldView, WORLD_M } from './world.js';
import { Driver } from './drive.js';
import { readAddress, keepInAddress } from '../address.js';
import { confirmFirst } from './confirm.js';

const DISCOVERY_MS = 2000;  // how often the set of turtles (and of Twist topics to drive) is refreshed
const DRIVE_PARAM = 'drive';  // ?drive=/rover/cmd_vel: the Twist topic driven, kept in the page's address
const $ = id => document.getElementById(id);

const view = new WorldView($('world'));
window.turtleView = view.debugHook();

let session = null;  // the connected RosSession, or null
let poses = new Map();  // turtle name -> its pose subscription
let cmdVel = null;  // {name, publisher} advertised on the current session
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

export function feedback(text, kind = 'info') {
  const list = $('feedback');
  if (list.firstChild?.lastChild.textContent === text) list.firstChild.remove();  // (e.g. every drive command refused)
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

// ---- the session ------------------------------------------------------------------------------

export function attach(connected) {
  session = connected;
  session.onStatus(status => status.level === 'error' && feedback(`Bridge: ${status.msg}`, 'error'));
  commandTopic();
  discoverTurtles();
  discoveryTimer = setInterval(discoverTurtles, DISCOVERY_MS);
}

export function detach() {
  session = null;
  cmdVel = null;
  poses = new Map();  // their subscriptions died with the socket
  clearInterval(discoveryTimer);
  view.breakTrails();
  driver.stop();  // nothing can be sent now; the turtle stops 1 s after its last command
}

// ---- discovery: the turtles ------------------------------------------------------------------

async function discoverTurtles() {
  const asked = session;
  if (!asked) return;
  try {
    const { topics, types } = await asked.rosapi('topics');
    if (asked !== session) return;
    trackTurtles(topics.filter((name, i) => types[i] === 'turtlesim/Pose' && /^\/[^/]+\/pose$/.test(name))
      .map(name => name.split('/')[1]));
    showTargets(topics.filter((name, i) => types[i] === 'geometry_msgs/Twist'));
  } catch (error) {
    feedback(`Could not list topics: ${error.message}`, 'error');
  }
}

function trackTurtles(names) {
  for (const [name, subscription] of poses) {
    if (names.includes(name)) continue;
    subscription.close();
    poses.delete(name);
  }
  for (const name of view.names) {
    if (!names.includes(name)) view.remove(name);
  }
  for (const name of names) {
    if (poses.has(name)) continue;
    poses.set(name, session.subscribe(`/${name}/pose`, 'turtlesim/Pose', pose => view.setPose(name, pose)));
  }
  showTarget();
}

// Every Twist topic of the graph can be driven; the one driven stays listed even before anyone uses it.
function showTargets(topics) {
  const select = $('target');
  const current = select.value;
  const wanted = [...new Set([...topics, current])].sort();
  if ([...select.options].map(o => o.value).join() === wanted.join()) return;
  select.replaceChildren(...wanted.map(name => new Option(name, name)));
  select.value = current;
}

function target() {
  return $('target').value;
}

// The turtle whose cmd_vel is driven (teleport acts on it), or null for another robot's topic.
function drivenTurtle() {
  const name = /^\/([^/]+)\/cmd_vel$/.exec(target())?.[1];
  return name && (poses.has(name) || !session) ? name : null;
}

function showTarget() {
  $('cmd-vel-name').textContent = target();
  for (const el of document.querySelectorAll('.target-name')) el.textContent = drivenTurtle() ?? '(drive a turtle)';
}

function startingTarget() {
  const asked = readAddress(DRIVE_PARAM)[0]?.trim();
  const valid = asked && /^\/[A-Za-z][\w]*(\/[A-Za-z][\w]*)*$/.test(asked);
  if (asked && !valid) feedback(`“${asked}” is not a topic name: driving /turtle1/cmd_vel.`, 'error');
  const name = valid ? asked : '/turtle1/cmd_vel';
  $('target').replaceChildren(new Option(name, name));
  showTarget();
}
startingTarget();

// ---- publishing Twists -------------------------------------------------------------------------

// The cmd_vel publisher of the driven turtle, advertised ahead of the first command (on connect and on
// a change of turtle) so that turtlesim is already subscribed when the first Twist goes out.
function commandTopic() {
  const name = target();
  if (cmdVel?.name !== name) {
    cmdVel?.publisher.close();
    const onError = text => feedback(`Cannot drive ${name}: ${text}`, 'error');
    cmdVel = { name, publisher: session.advertise(name, 'geometry_msgs/Twist', { queue_size: 1, onError }) };
  }
  return cmdVel.publisher;
}

// Resolves once the bridge had time to refuse the Twist, rejects with its error; null when not connected (never
// queued while disconnected: a stale command must not move the turtle after a reconnect).
function publishTwist(linear, angular) {
  if (!session) return null;
  return (cmdVel?.publisher ?? commandTopic()).publish({
    linear: { x: linear, y: 0, z: 0 },
    angular: { x: 0, y: 0, z: angular },
  });
}

// Says what became of a Twist sent on the driven topic: `done` once the bridge had time to refuse it.
function report(sent, done) {
  const name = target();
  if (!sent) {
    feedback('Nothing published: not connected to the bridge.', 'error');
    return;
  }
  sent.then(() => done && feedback(done, 'ok'),
    error => feedback(`Not published on ${name}: ${error.message}`, 'error'));
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
  report(publishTwist(speeds.linear, speeds.angular),
    `Published linear.x = ${speeds.linear}, angular.z = ${speeds.angular} on ${target()}.`);
});

const driver = new Driver({
  publish: (linear, angular) => session && report(publishTwist(linear, angular)),
  // Full stick = the tutorial speeds' magnitudes; the keys give the direction.
  speeds: () => {
    const speeds = tutorialSpeeds();
    return speeds && { linear: Math.abs(speeds.linear), angular: Math.abs(speeds.angular) };
  },
  joystick: $('joystick'),
});

// The driven robot is stopped first: its zero Twist still goes to the publisher of the old name.
function switchTarget() {
  driver.stop();
  showTarget();
  keepInAddress(DRIVE_PARAM, [target()]);
  if (session) commandTopic();
}

$('target').addEventListener('change', switchTarget);

$('stop').addEventListener('click', () => {
  driver.stop();
  report(publishTwist(0, 0), `Stopped: a zero Twist on ${target()}.`);
});

// ---- services ----------------------------------------------------------------------------------

async function callService(name, type, args, done) {
  if (!session) {
    serviceStatus(`Not connected: ${name} was not called.`, 'error');
    return;
  }
  serviceStatus(`Calling ${name}…`);
  try {
    serviceStatus(done(await session.call(name, type, args)), 'ok');
    discoverTurtles();
  } catch (error) {
    serviceStatus(`${name} failed: ${error.message || 'the service reported an error'}`, 'error');
  }
}

$('clear').addEventListener('click', async () => {
  if (!await confirmFirst($('clear'), 'Clear every trail? This cannot be undone.', 'Clear trails')) return;
  callService('/clear', 'std_srvs/Empty', {}, () => {
    view.clearTrails();
    return 'Trails cleared.';
  });
});

$('reset').addEventListener('click', async () => {
  const question = 'Reset the world? Every turtle but a new turtle1 is removed, with the trails. ' +
    'This cannot be undone.';
  if (!await confirmFirst($('reset'), question, 'Reset')) return;
  callService('/reset', 'std_srvs/Empty', {}, () => {
    view.forgetTurtles();
    return 'World reset: turtle1 is back in the centre.';
  });
});

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
  const name = drivenTurtle();
  if (!name) {
    serviceStatus(`${target()} is not a turtle's cmd_vel: choose a turtle to teleport under Drive.`, 'error');
    return;
  }
  callService(`/${name}/teleport_absolute`, 'turtlesim/TeleportAbsolute', { x, y, theta },
    () => `Teleported ${name} to (${x}, ${y}, ${theta}).`);
});

