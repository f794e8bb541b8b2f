// Driving: the Twist topic driven (any geometry_msgs/Twist topic of the graph; the page's address keeps it as
// ?drive=/rover/cmd_vel), the keys and the joystick (driver.js), and Stop. It owns the topic's publisher on the
// current session: the Twist form publishes through it, and the world's tools ask it which turtle is driven.
// Under the joystick, the readout of what a driver watches: the driven robot's pose and speed (its turtle's
// turtlesim/Pose, or its nav_msgs/Odometry), drawn at the next animation frame after each message, with its age.
import { Panel } from '../parts/panel.js';
import { Driver } from '../parts/driver.js';
import { turtlesIn } from './world.js';
import { readAddress, keepInAddress } from '../address.js';
import { formatAge } from '../format.js';

const DISCOVERY_MS = 2000;  // how often the Twist topics (and the turtles) of the graph are refreshed
const DRIVE_PARAM = 'drive';
const DEFAULT_TOPIC = '/turtle1/cmd_vel';
const AGE_MS = 250;  // how often the readout's age is shown again while no message comes

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
      </div>
      <p class="readout" hidden aria-live="off"><code class="readout-topic"></code>
        <span class="readout-values"></span> <span class="readout-age"></span></p>`;
    this.select = root.querySelector('#target');
    this.turtles = null;  // the graph's turtles as last seen; null until this connection's first look
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
    this.readout = new Readout(root.querySelector('.readout'));
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

  // The turtle whose cmd_vel is driven (teleport acts on it), or null for another robot's topic. Before the graph
  // is seen, a turtle's cmd_vel is taken at its name: a teleport clicked as the page connects goes (turtlesim
  // answers if there is no such turtle), where it was refused as "not a turtle's cmd_vel".
  turtle() {
    const name = /^\/([^/]+)\/cmd_vel$/.exec(this.topic)?.[1];
    return name && (!this.session || !this.turtles || this.turtles.has(name)) ? name : null;
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
    this.turtles = null;
    this.commandTopic();
    this.discover();
    this.timer = setInterval(() => this.discover(), DISCOVERY_MS);
  }

  detach() {
    super.detach();
    this.cmdVel = null;  // (gone with the socket)
    this.readout.detach();
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
      this.readout.watch(asked, this.watchedTopic(topics, types));
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

  // [name, type] of what the driven robot says of its pose and speed: its turtle's pose, else the odometry beside
  // its command topic (/rover/cmd_vel: /rover/odom), else /odom; null when there is none.
  watchedTopic(topics, types) {
    const turtle = this.turtle();
    if (turtle) return [`/${turtle}/pose`, 'turtlesim/Pose'];
    const odometry = topics.filter((name, i) => types[i] === 'nav_msgs/Odometry');
    const beside = `${this.topic.replace(/\/[^/]*$/, '')}/odom`;
    const name = [beside, '/odom'].find(n => odometry.includes(n)) ?? odometry.sort()[0];
    return name ? [name, 'nav_msgs/Odometry'] : null;
  }

  // The driven robot is stopped first: its zero Twist still goes to the publisher of the old name.
  switchTopic() {
    this.driver.stop();
    keepInAddress(DRIVE_PARAM, [this.topic]);
    if (this.session) {
      this.commandTopic();
      this.discover();  // (the readout follows the robot driven)
    }
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

// The pose and speed of the robot driven, as fresh as they come: a message is drawn at the next animation frame
// (one drawing per frame whatever the rate), and its age is shown from its header.stamp when it has one (by the
// bridge's clock, RosSession.ageOf), else from when it arrived, saying which.
class Readout {
  constructor(element) {
    this.element = element;
    [this.topicText, this.values, this.age] = element.children;
    this.watched = null;  // [name, type]
    this.subscription = null;
    this.session = null;
    this.latest = null;  // { message, arrived (ms), age at arrival (s) or null }
    this.frame = null;
    setInterval(() => this.showAge(), AGE_MS);  // (while disconnected too: the value shown grows older)
  }

  watch(session, watched) {
    if (session === this.session && watched?.[0] === this.watched?.[0]) return;
    this.detach();
    this.session = session;
    if (watched?.[0] !== this.watched?.[0]) {  // another robot's: nothing of the last one stays
      this.latest = null;
      this.values.textContent = this.age.textContent = '';
    }
    this.watched = watched;
    this.element.hidden = !watched;
    if (!watched) return;
    const [name, type] = watched;
    this.topicText.textContent = name;
    this.subscription = session.subscribe(name, type, message => this.receive(message));
  }

  detach() {
    this.subscription?.close();
    this.subscription = null;
    this.session = null;
    cancelAnimationFrame(this.frame);
    this.frame = null;
  }

  receive(message) {
    this.latest = { message, arrived: performance.now(), age: this.session?.ageOf(message.header?.stamp) ?? null };
    this.frame ??= requestAnimationFrame(() => {
      this.frame = null;
      this.show();
    });
  }

  show() {
    const latest = this.latest;
    if (!latest || !this.watched) return;
    const m = latest.message;
    const [x, y, theta, linear, angular] = this.watched[1] === 'turtlesim/Pose'
      ? [m.x, m.y, m.theta, m.linear_velocity, m.angular_velocity]
      : [m.pose.pose.position.x, m.pose.pose.position.y, yaw(m.pose.pose.orientation), m.twist.twist.linear.x,
        m.twist.twist.angular.z];
    const text = `x ${fixed(x)} y ${fixed(y)} θ ${fixed(theta)} · ${fixed(linear)} m/s ${fixed(angular)} rad/s`;
    if (this.values.textContent !== text) this.values.textContent = text;
    // the age at once the first time, then by AGE_MS's timer: a text changing at every frame would cost a layout
    // at every frame, and say nothing an eye can read
    if (!this.age.textContent) this.showAge();
  }

  showAge() {
    const latest = this.latest;
    if (!latest) return;
    const since = (performance.now() - latest.arrived) / 1000;
    const text = latest.age === null ? `${formatAge(since)} since it arrived`
      : `${formatAge(latest.age + since)} old (stamp)`;
    if (this.age.textContent !== text) this.age.textContent = text;
  }
}

function yaw({ x, y, z, w }) {
  return Math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));
}

function fixed(value) {
  return typeof value === 'number' ? value.toFixed(2) : '—';
}
