// One rosbridge connection that heals itself: after a close or a failed attempt it retries with
// exponential backoff. Every successful attempt gets a fresh ROSLIB.Ros, because subscriptions and
// advertisements live on the server side of a socket and must be made again on the new one.
const FIRST_RETRY_MS = 500;
const MAX_RETRY_MS = 5000;

export class Connection {
  // onState(state, detail): state is 'connecting' | 'connected' | 'closed' | 'error'.
  // onOpen(ros) / onLost(): a usable ROSLIB.Ros appeared / went away.
  constructor(url, { onState, onOpen, onLost }) {
    this.url = url;
    this.onState = onState;
    this.onOpen = onOpen;
    this.onLost = onLost;
    this.ros = null;  // set only while connected
    this.retryMs = FIRST_RETRY_MS;
    this.everConnected = false;
    this.retrying = false;
  }

  start() {
    this.attempt();
  }

  attempt() {
    const ros = new ROSLIB.Ros();
    let opened = false;
    let ended = false;
    ros.on('connection', () => {
      opened = true;
      this.everConnected = true;
      this.retryMs = FIRST_RETRY_MS;
      this.retrying = false;
      this.ros = ros;
      this.onState('connected', this.url);
      this.onOpen(ros);
    });
    const end = () => {  // 'error' and 'close' may both fire for one failure
      if (ended) return;
      ended = true;
      ros.close();
      if (opened) {
        this.ros = null;
        this.onLost();
      }
      const delay = this.retryMs;
      this.retryMs = Math.min(this.retryMs * 2, MAX_RETRY_MS);
      // Once we have been connected, losing the bridge reads as "closed" until it is back.
      this.retrying = true;
      this.onState(this.everConnected ? 'closed' : 'error', delay);
      setTimeout(() => this.attempt(), delay);
    };
    ros.on('close', end);
    ros.on('error', end);
    // Retries keep showing why we retry ("closed"/"error") instead of flickering to "connecting".
    if (!this.retrying) this.onState('connecting', this.url);
    ros.connect(this.url);
  }
}

// The bridge serves this page and the websocket on the same host, port and path.
export function bridgeUrl(loc = window.location) {
  return `${loc.protocol === 'https:' ? 'wss' : 'ws'}://${loc.host}/`;
}
