// Camera: any topic the image viewer (viewers/image.js) draws, chosen from a list and shown live; the viewer asks
// the bridge for binary frames, the newest only.
import { ListPanel, fillSelect } from './panel.js';
import { ImageViewer } from '../viewers/image.js';

export class CameraPanel extends ListPanel {
  constructor(root, page) {
    super(root, page, 'Could not list topics');
    root.innerHTML = `
      <p class="hint">Any sensor_msgs/Image or CompressedImage topic, as binary CBOR; only the newest frame
        is sent when the page falls behind.</p>
      <p class="panel-status error" role="status"></p>
      <label for="camera-topic" class="sr-only">Camera topic</label>
      <select id="camera-topic" class="camera-topic"></select>
      <div class="camera-view"></div>`;
    this.select = root.querySelector('select');
    this.view = root.querySelector('.camera-view');
    this.viewer = null;
    this.watched = '';  // the topic the viewer shows
    this.subscription = null;
    this.types = new Map();
    this.select.addEventListener('change', () => this.watch(this.select.value));
  }

  detach() {
    super.detach();
    this.subscription = null;  // (gone with the socket)
    this.shown = null;  // so that the next session watches the chosen camera again
  }

  async load(session) {
    const { topics, types } = await session.rosapi('topics');
    const pictured = type => this.page.viewersFor(type).some(row => row.Viewer === ImageViewer);
    return topics.map((name, i) => [name, types[i]]).filter(([, type]) => pictured(type))
      .sort(([a], [b]) => a.localeCompare(b));
  }

  render(cameras) {
    this.types = new Map(cameras);
    fillSelect(this.select, cameras.length ? 'Choose a camera…' : 'No image topics',
      cameras.map(([name, type]) => [name, `${name} (${type.split('/')[1]})`]));
    if (this.select.value && !this.subscription) this.watch(this.select.value);
  }

  watch(topic) {
    this.subscription?.close();
    this.subscription = null;
    if (topic !== this.watched) {  // (the same camera after a reconnection keeps its last picture meanwhile)
      this.viewer?.close();
      this.view.replaceChildren();
      this.viewer = topic ? new ImageViewer(this.view, { topic, type: this.types.get(topic) }) : null;
      this.watched = topic;
    }
    if (!topic || !this.session) return;
    const viewer = this.viewer;
    this.subscription = this.session.subscribe(topic, viewer.type, message => viewer.draw(message),
      ImageViewer.subscription);
  }
}
