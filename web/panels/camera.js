// Camera: the driver's view, in the world's card between the world and the joystick. Any topic the image viewer
// (viewers/image.js) draws, chosen from a list and shown live; the address keeps the one shown
// (?camera=/turtle_camera/image_raw). While a camera is shown, the world becomes a small map beside the joystick
// (style.css, .world.camera-on), so that the picture, the robot's pose and speed (drive.js's readout) and the
// joystick are on one screen, a phone's too. The panel is hidden while the graph has no image topic.
//
// The viewer brings its pictures by the bridge's JPEG stream when there is one; only without it does this panel
// subscribe to the topic over the websocket for it (binary, the newest frame only).
import { ListPanel, fillSelect } from '../parts/panel.js';
import { ImageViewer } from '../viewers/image.js';
import { readAddress, keepInAddress } from '../address.js';

const CAMERA_PARAM = 'camera';
const REFRESH_MS = 3000;  // how often the image topics of the graph are listed again

export class CameraPanel extends ListPanel {
  constructor(root, page) {
    super(root, page, 'Could not list topics');
    root.classList.add('camera-panel');
    root.hidden = true;
    root.innerHTML = `
      <div class="camera-choice">
        <label for="camera-topic">Camera</label>
        <select id="camera-topic" class="camera-topic"></select>
      </div>
      <p class="panel-status error" role="status"></p>
      <div class="camera-view"></div>`;
    this.select = root.querySelector('select');
    this.view = root.querySelector('.camera-view');
    this.viewer = null;
    this.watched = '';  // the topic the viewer shows
    this.asked = readAddress(CAMERA_PARAM)[0] ?? '';  // the address's camera, chosen once it is listed
    this.subscription = null;
    this.types = new Map();
    this.timer = null;
    this.select.addEventListener('change', () => {
      this.asked = '';
      this.watch(this.select.value);
    });
  }

  attach(session) {
    super.attach(session);  // (lists the cameras, then shows the one chosen)
    this.timer = setInterval(() => this.refresh(), REFRESH_MS);
    this.connectViewer();
  }

  detach() {
    super.detach();
    clearInterval(this.timer);
    this.viewer?.detach();
    this.subscription = null;  // (gone with the socket)
  }

  async load(session) {
    const { topics, types } = await session.rosapi('topics');
    const pictured = type => this.page.viewersFor(type).some(row => row.Viewer === ImageViewer);
    return topics.map((name, i) => [name, types[i]]).filter(([, type]) => pictured(type))
      .sort(([a], [b]) => a.localeCompare(b));
  }

  render(cameras) {
    for (const [name, type] of cameras) this.types.set(name, type);
    const listed = cameras.map(([name]) => name);
    // the camera shown stays listed while its topic is gone (its node restarting, say)
    const choices = this.watched && !listed.includes(this.watched) ? [...listed, this.watched].sort() : listed;
    fillSelect(this.select, 'No camera', choices.map(name => [name, `${name} (${this.types.get(name).split('/')[1]})`]));
    if (this.asked && listed.includes(this.asked)) {
      this.select.value = this.asked;
      this.asked = '';
    }
    this.root.hidden = !choices.length;
    if (this.select.value !== this.watched) this.watch(this.select.value);
  }

  watch(topic) {
    if (topic === this.watched) return;
    this.subscription?.close();
    this.subscription = null;
    this.viewer?.close();
    this.view.replaceChildren();
    this.watched = topic;
    this.viewer = topic ? new ImageViewer(this.view, { topic, type: this.types.get(topic),
      onChange: () => this.subscribeViewer() }) : null;
    this.root.closest('.world')?.classList.toggle('camera-on', Boolean(topic));
    keepInAddress(CAMERA_PARAM, topic ? [topic] : []);
    this.connectViewer();
  }

  connectViewer() {
    if (!this.viewer || !this.session) return;
    this.viewer.attach(this.session);
    this.subscribeViewer();
  }

  // Over the websocket only when the viewer has no stream.
  subscribeViewer() {
    this.subscription?.close();
    this.subscription = null;
    const viewer = this.viewer;
    if (!viewer || !this.session || viewer.streamed) return;
    this.subscription = this.session.subscribe(viewer.topic, viewer.type, message => viewer.draw(message),
      viewer.subscription);
  }
}
