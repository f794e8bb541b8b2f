// Driving: the Twist topic driven (any geometry_msgs/Twist topic of the graph; the page's address keeps it as
// ?drive=/rover/cmd_vel), the keys and the joystick (driver.js), and Stop. It owns the topic's publisher on the
// current session: the Twist form publishes through it, and the world's tools ask it which turtle is driven.
import { Panel } from './panel.js';
import { Driver } from './driver.js';
import { turtlesIn } from './turtles.js';
import { readAddress, keepInAddress } from '../address.js';

const DISCOVERY_MS = 2000;  // how often the Twist topics (and the turtles) of the graph are refreshed
const DRIVE_PARAM = 'drive';
const DEFAULT_TOPIC = '/turtle1/cmd_vel';

export class DrivePanel extends Panel {
  constructor(root, page) {
    super(root, page);
    root.classList.add('drive');
    root.innerHTML = `
      <div id="joystick" class="joystick" role="group"
        aria-label="Joystick: drag to drive; the arrow keys do the same"><div class="knob"></div></div>
      <div class="drive-help">
        <label for="target">Drive <small>(any <code>geometry_msgs/Twist</code> topic)</small></label>
        <div class="drive-target">
          <select id="target"></select>
          <button id="stop" type="button" class="stop" title="Publish a zero Twist now">Stop</button>
        </div>
        <p><span class="for-keys">Hold <kbd>↑</kbd><kbd>↓</kbd><kbd>←</kbd><kbd>→</kbd> or
          <kbd>W</kbd><kbd>A</kbd><kbd>S</kbd><kbd>D</kbd>, or drag the joystick.</span>
          <span class="for-touch">Hold the joystick and slide: up drives forward, sideways turns.</span>
          Top speeds are Linear&nbsp;X and Angular&nbsp;Z.</p>
      </div>`;
    this.select = root.querySelector('#target');
    this.turtles = new Set();  // the graph's turtles, as last seen
    this.cmdVel = null;  // {name, publisher} advertised on the current session
    this.listeners = [];
    this.timer = null;
    this.driver = new Driver({
      publish: (linear, angular) => this.session && this.report(this.publish(linear, angular)),
      // Full stick = the Twist form's speeds' magnitudes; the keys give the direction.
      speeds: () => {
        const speeds = this.page.panels.get('twist').speeds();
        return speeds && { linear: Math.abs(speeds.linear), angular: Math.abs(speeds.angular) };
      },
      joystick: root.querySelector('#joystick'),
    });
    this.select.addEventListener('change', () => this.switchTopic());
    root.querySelector('#stop').addEventListener('click', () => {
      this.driver.stop();
      this.report(this.publish(0, 0), `Stopped: a zero Twist on ${this.topic}.`);
    });
    this.startingTopic();
  }

  get topic() {
    return this.select.value;
  }

  // The turtle whose cmd_vel is driven (teleport acts on it), or null for another robot's topic.
  turtle() {
    const name = /^\/([^/]+)\/cmd_vel$/.exec(this.topic)?.[1];
    return name && (this.turtles.has(name) || !this.session) ? name : null;
  }

  // listener() now and whenever the topic driven or the turtle it moves may have changed.
  onChange(listener) {
    this.listeners.push(listener);
    listener();
  }

  changed() {
    for (const listener of this.listeners) listener();
  }

  attach(session) {
    super.attach(session);
    this.commandTopic();
    this.discover();
    this.timer = setInterval(() => this.discover(), DISCOVERY_MS);
  }

  detach() {
    super.detach();
    this.cmdVel = null;  // (gone with the socket)
    clearInterval(this.timer);
    this.driver.stop();  // nothing can be sent now; the turtle stops 1 s after its last command
  }

  startingTopic() {
    const asked = readAddress(DRIVE_PARAM)[0]?.trim();
    const valid = asked && /^\/[A-Za-z][\w]*(\/[A-Za-z][\w]*)*$/.test(asked);
    if (asked && !valid) this.page.feedback.add(`“${asked}” is not a topic name: driving ${DEFAULT_TOPIC}.`, 'error');
    const name = valid ? asked : DEFAULT_TOPIC;
    this.select.replaceChildren(new Option(name, name));
  }

  // Every Twist topic of the graph can be driven; the one driven stays listed even before anyone uses it.
  async discover() {
    const asked = this.session;
    if (!asked) return;
    try {
      const { topics, types } = await asked.rosapi('topics');
      if (asked !== this.session) return;
      this.turtles = new Set(turtlesIn(topics, types));
      this.showTopics(topics.filter((name, i) => types[i] === 'geometry_msgs/Twist'));
      this.changed();
    } catch {
      // (the world panel says so: it asks the same question)
    }
  }

  showTopics(topics) {
    const current = this.topic;
    const wanted = [...new Set([...topics, current])].sort();
    if ([...this.select.options].map(o => o.value).join() === wanted.join()) return;
    this.select.replaceChildren(...wanted.map(name => new Option(name, name)));
    this.select.value = current;
  }

  // The driven robot is stopped first: its zero Twist still goes to the publisher of the old name.
  switchTopic() {
    this.driver.stop();
    keepInAddress(DRIVE_PARAM, [this.topic]);
    if (this.session) this.commandTopic();
    this.changed();
  }

  // The publisher of the driven topic, advertised ahead of the first command (on connect and on a change of
  // topic) so that turtlesim is already subscribed when the first Twist goes out.
  commandTopic() {
    const name = this.topic;
    if (this.cmdVel?.name !== name) {
      this.cmdVel?.publisher.close();
      const onError = text => this.page.feedback.add(`Cannot drive ${name}: ${text}`, 'error');
      this.cmdVel = { name, publisher: this.session.advertise(name, 'geometry_msgs/Twist', { queue_size: 1, onError }) };
    }
    return this.cmdVel.publisher;
  }

  // Resolves once the bridge had time to refuse the Twist, rejects with its error; null when not connected (never
  // queued while disconnected: a stale command must not move the turtle after a reconnect).
  publish(linear, angular) {
    if (!this.session) return null;
    return (this.cmdVel?.publisher ?? this.commandTopic()).publish({
      linear: { x: linear, y: 0, z: 0 },
      angular: { x: 0, y: 0, z: angular },
    });
  }

  // Says in the feedback what became of a Twist sent by publish(): `done` once the bridge had time to refuse it.
  report(sent, done) {
    const name = this.topic;
    const feedback = this.page.feedback;
    if (!sent) {
      feedback.add('Nothing published: not connected to the bridge.', 'error');
      return;
    }
    sent.then(() => done && feedback.add(done, 'ok'),
      error => feedback.add(`Not published on ${name}: ${error.message}`, 'error'));
  }
}
