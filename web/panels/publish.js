// Publish anything (rostopic pub): a topic and a message type; a form generated from the type's definition;
// publish once, or at a rate until stopped.
import { messageForm } from '../parts/messages.js';
import { Panel } from '../parts/panel.js';

const MAX_RATE_HZ = 100;

export class PublishPanel extends Panel {
  constructor(root, page) {
    super(root, page);
    root.innerHTML = `
      <p class="hint">rostopic pub, for any message type: a form made from its definition.</p>
      <div class="row">
        <label>Topic <input class="publish-topic" autocomplete="off" spellcheck="false" value="/turtle1/cmd_vel"></label>
        <label>Type <input class="publish-type" autocomplete="off" spellcheck="false" value="geometry_msgs/Twist"></label>
        <button type="button" class="publish-load">Load form</button>
      </div>
      <div class="publish-form service-form"></div>
      <div class="row">
        <button type="button" class="publish-once primary">Publish once</button>
        <label>Rate <input class="publish-rate" inputmode="decimal" value="10" size="5"> Hz</label>
        <button type="button" class="publish-repeat">Publish at rate</button>
      </div>
      <p class="publish-status" role="status" aria-live="polite"></p>`;
    this.topicInput = root.querySelector('input.publish-topic');
    this.typeInput = root.querySelector('input.publish-type');
    this.formArea = root.querySelector('.publish-form');
    this.rateInput = root.querySelector('input.publish-rate');
    this.status = root.querySelector('.publish-status');
    this.form = null;
    this.publisher = null;  // {topic, type, publish, close} on the current session
    this.timer = null;
    root.querySelector('button.publish-load').addEventListener('click', () => this.load());
    root.querySelector('button.publish-once').addEventListener('click', () => this.publishOnce());
    root.querySelector('button.publish-repeat').addEventListener('click', () => this.toggleRepeat());
    this.topicInput.addEventListener('change', () => this.guessType());
  }

  detach() {
    super.detach();
    this.stopRepeat();
    this.publisher = null;  // (gone with the socket)
  }

  // A topic someone already publishes has a type: fill it in.
  async guessType() {
    if (!this.session || this.typeInput.value.trim()) return;
    try {
      const { type } = await this.session.rosapi('topic_type', { topic: this.topicInput.value.trim() });
      if (type && !this.typeInput.value.trim()) this.typeInput.value = type;
    } catch {
      // no such topic yet: the person types the type
    }
  }

  async load() {
    const type = this.typeInput.value.trim();
    if (!this.session) return this.say('Not connected.', 'error');
    if (!/^[A-Za-z][\w]*\/[A-Za-z]\w*$/.test(type)) return this.say('Type a message type like geometry_msgs/Twist.', 'error');
    try {
      const { typedefs } = await this.session.rosapi('message_details', { type });
      if (!typedefs.length) return this.say(`Unknown message type ${type}.`, 'error');
      this.form = messageForm(typedefs);
      this.formType = type;
      this.formArea.replaceChildren(this.form.element);
      this.say(`A ${type}: fill it in, then publish.`, 'info');
    } catch (error) {
      this.say(`Unknown message type ${type}: ${error.message}`, 'error');
    }
  }

  publishOnce() {
    const topic = this.topicInput.value.trim();
    this.send()?.then(() => this.say(`Published on ${topic}.`, 'ok'), error => this.refused(topic, error));
  }

  // Sends the form's message; a promise of its fate, or undefined (said why) when nothing could be sent.
  send() {
    const topic = this.topicInput.value.trim();
    if (!this.session) return this.say('Not connected: nothing published.', 'error');
    if (!this.form) return this.say('Load a message type first.', 'error');
    if (!/^\/?[A-Za-z~][\w/]*$/.test(topic)) return this.say(`“${topic}” is not a topic name.`, 'error');
    const message = this.form.read();
    if (message === null) return this.say('Nothing published: fix the highlighted fields.', 'error');
    if (this.publisher?.topic !== topic || this.publisher?.type !== this.formType) {
      this.publisher?.close();
      const onError = text => this.refused(topic, new Error(text));
      this.publisher = { topic, type: this.formType, ...this.session.advertise(topic, this.formType, { onError }) };
    }
    this.say(`Publishing on ${topic}…`, 'info');
    return this.publisher.publish(message);
  }

  refused(topic, error) {
    this.stopRepeat();
    this.say(`Not published on ${topic}: ${error.message}`, 'error');
  }

  toggleRepeat() {
    if (this.timer) {
      this.stopRepeat();
      return;
    }
    const rate = Number(this.rateInput.value.replace(',', '.'));
    if (!(rate > 0 && rate <= MAX_RATE_HZ)) {
      this.say(`Rate: a number of Hz, up to ${MAX_RATE_HZ}.`, 'error');
      return;
    }
    const topic = this.topicInput.value.trim();
    const repeat = () => {
      const sent = this.send();
      sent?.catch(error => this.refused(topic, error));
      return sent;
    };
    if (!repeat()) return;
    this.timer = setInterval(() => repeat() || this.stopRepeat(), 1000 / rate);
    this.root.querySelector('button.publish-repeat').textContent = 'Stop';
  }

  stopRepeat() {
    clearInterval(this.timer);
    this.timer = null;
    this.root.querySelector('button.publish-repeat').textContent = 'Publish at rate';
  }

  say(text, kind) {  // (undefined: so that `return this.say(...)` says nothing was sent)
    this.status.textContent = text;
    this.status.className = `publish-status ${kind}`;
  }
}
