// Services (rosservice list / info / call, rossrv show): every service with its type; choosing one shows a
// form generated from its request definition; calling it shows the response, or the error.
import { definitionText, messageForm, messageTree } from '../parts/messages.js';
import { ListPanel, fillSelect } from '../parts/panel.js';
import { confirmFirst } from '../parts/confirm.js';

// Services whose call cannot be undone (turtlesim's /kill, /clear, /reset, rosapi's delete_param...): asked first.
const IRREVERSIBLE = /\/(kill|clear|reset|delete\w*|shutdown)$/;

export class ServicesPanel extends ListPanel {
  constructor(root, page) {
    super(root, page, 'Could not list services');
    root.innerHTML = `
      <p class="hint">rosservice list · call, and rossrv show. <span class="service-count muted"></span></p>
      <p class="panel-status error" role="status"></p>
      <form class="service-call" novalidate>
        <div class="row"><label for="service-name" class="sr-only">Service</label>
          <select id="service-name" class="service-name"></select>
          <button type="submit" class="primary">Call</button></div>
        <div class="service-form"></div>
      </form>
      <div class="service-result" role="status" aria-live="polite"></div>`;
    this.select = root.querySelector('select.service-name');
    this.count = root.querySelector('.service-count');
    this.formArea = root.querySelector('.service-form');
    this.result = root.querySelector('.service-result');
    this.form = null;
    this.asking = false;
    this.select.addEventListener('change', () => this.choose(this.select.value));
    root.querySelector('form').addEventListener('submit', e => {
      e.preventDefault();
      this.callChosen();
    });
  }

  async load(session) {
    return [...(await session.rosapi('services')).services].sort();
  }

  render(names) {
    this.count.textContent = `(${names.length})`;
    fillSelect(this.select, 'Choose a service…', names.map(n => [n, n]));
  }

  async choose(name) {
    this.formArea.replaceChildren();
    this.result.replaceChildren();
    this.chosen = null;
    if (!name || !this.session) return;
    try {
      const { type } = await this.session.rosapi('service_type', { service: name });
      const [request, response] = await Promise.all([
        this.session.rosapi('service_request_details', { type }),
        this.session.rosapi('service_response_details', { type })]);
      if (this.select.value !== name) return;
      this.chosen = { name, type };
      this.form = messageForm(request.typedefs);
      const heading = document.createElement('p');
      heading.className = 'muted';
      heading.innerHTML = 'Type <code></code>';
      heading.lastChild.textContent = type;
      const definition = document.createElement('details');
      definition.className = 'definition';
      definition.innerHTML = '<summary>Definition <small>(rossrv show)</small></summary><pre></pre>';
      definition.lastChild.textContent = `${definitionText(request.typedefs)}\n---\n${definitionText(response.typedefs)}`;
      this.formArea.append(heading, definition, this.form.element);
    } catch (error) {
      this.showError(`Could not read ${name}'s type: ${error.message}`);
    }
  }

  async callChosen() {
    if (!this.chosen || !this.session) {
      this.showError(this.session ? 'Choose a service first.' : 'Not connected.');
      return;
    }
    const request = this.form.read();
    if (request === null) {
      this.showError('Not called: fix the highlighted fields.');
      return;
    }
    const { name, type } = this.chosen;
    if (IRREVERSIBLE.test(name)) {
      if (this.asking) return;  // (Enter in a field while the question is shown)
      this.asking = true;
      const agreed = await confirmFirst(this.root.querySelector('button[type=submit]'),
        `Call ${name}? This cannot be undone.`, 'Call');
      this.asking = false;
      if (!agreed) return;
    }
    this.result.textContent = `Calling ${name}…`;
    try {
      const response = await this.session.call(name, type, request);
      const title = document.createElement('p');
      title.className = 'ok';
      title.textContent = `${name} answered:`;
      this.result.replaceChildren(title, messageTree(response));
    } catch (error) {
      this.showError(`${name} failed: ${error.message}`);
    }
  }

  showError(text) {
    const line = document.createElement('p');
    line.className = 'error';
    line.textContent = text;
    this.result.replaceChildren(line);
  }
}
