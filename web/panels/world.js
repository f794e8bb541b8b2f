// The live world, the first thing one sees: every turtle of the graph (each /<name>/pose of type turtlesim/Pose)
// drawn where it is, with the trail it leaves while the page is open (parts/world-view.js draws). Its subscriptions are the
// current session's, dropped in detach().
import { Panel } from '../parts/panel.js';
import { WorldView } from '../parts/world-view.js';

const DISCOVERY_MS = 2000;  // how often the set of turtles is refreshed

export class WorldPanel extends Panel {
  constructor(root, page) {
    super(root, page);
    root.classList.add('turtles');
    root.innerHTML = '<div class="stage"><canvas id="world" role="img" ' +
      'aria-label="Live view of the turtles and their trails"></canvas></div>';
    this.view = new WorldView(root.querySelector('canvas'));
    window.turtleView = this.view.debugHook();
    this.poses = new Map();  // turtle name -> its pose subscription
    this.timer = null;
  }

  attach(session) {
    super.attach(session);
    this.discover();
    this.timer = setInterval(() => this.discover(), DISCOVERY_MS);
  }

  detach() {
    super.detach();
    clearInterval(this.timer);
    this.poses = new Map();  // their subscriptions died with the socket
    this.view.breakTrails();
  }

  // Looks for turtles now (after a spawn or a reset, rather than at the next round).
  async discover() {
    const asked = this.session;
    if (!asked) return;
    try {
      const { topics, types } = await asked.rosapi('topics');
      if (asked === this.session) this.track(turtlesIn(topics, types));
    } catch (error) {
      this.page.feedback.add(`Could not list topics: ${error.message}`, 'error');
    }
  }

  track(names) {
    for (const [name, subscription] of this.poses) {
      if (names.includes(name)) continue;
      subscription.close();
      this.poses.delete(name);
    }
    for (const name of this.view.names) {
      if (!names.includes(name)) this.view.remove(name);
    }
    for (const name of names) {
      if (this.poses.has(name)) continue;
      this.poses.set(name, this.session.subscribe(`/${name}/pose`, 'turtlesim/Pose',
        pose => this.view.setPose(name, pose)));
    }
  }

  // Like turtlesim's /clear: the trails go, the turtles stay.
  clearTrails() {
    this.view.clearTrails();
  }

  // After /reset the old turtles are gone: no line may join an old pose to the new turtle1.
  forgetTurtles() {
    this.view.forgetTurtles();
  }
}

// The turtles of rosapi's topic list: the names of its /<name>/pose topics of type turtlesim/Pose.
export function turtlesIn(topics, types) {
  return topics.filter((name, i) => types[i] === 'turtlesim/Pose' && /^\/[^/]+\/pose$/.test(name))
    .map(name => name.split('/')[1]);
}
