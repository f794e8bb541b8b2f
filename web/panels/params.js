// Parameters (rosparam list / get / set / delete): every parameter with its value; editing keeps its type
// (a number stays a number, a list a list); a value that does not fit is flagged under its field.
import { ListPanel } from '../parts/panel.js';

export class ParamsPanel extends ListPanel {
  constructor(root, page) {
    super(root, page, 'Could not list parameters');
    root.innerHTML = `
      <p class="hint">rosparam list · get · set · delete: a value keeps its type (numbers, true/false,
        JSON lists and dictionaries). <span class="param-count muted"></span></p>
      <p class="panel-status error" role="status"></p>
      <p class="param-status" role="status" aria-live="polite"></p>
      <div class="scroll"><table class="param-list"><tbody></tbody></table></div>`;
    this.list = root.querySelector('.param-list tbody');
    this.count = root.querySelector('.param-count');
    this.result = root.querySelector('.param-status');
  }

  async load(session) {
    const names = [...(await session.rosapi('get_param_names')).names].sort();
    const values = await Promise.all(names.map(name =>
      session.rosapi('get_param', { name }).then(r => JSON.parse(r.value), () => undefined)));
    return names.map((name, i) => [name, values[i]]);
  }

  render(params) {
    this.count.textContent = `(${params.length})`;
    this.list.replaceChildren(...params.map(([name, value]) => this.row(name, value)));
  }

  row(name, value) {
    const row = document.createElement('tr');
    row.dataset.param = name;
    row.innerHTML = `<td><code></code></td><td><form class="param-edit" novalidate>
        <input autocomplete="off" spellcheck="false" aria-label="value"><button type="submit">Set</button>
        <button type="button" class="delete">Delete</button><p class="err" hidden></p></form></td>`;
    row.querySelector('code').textContent = name;
    const input = row.querySelector('input');
    input.value = typeof value === 'string' ? value : JSON.stringify(value);
    row.querySelector('form').addEventListener('submit', e => {
      e.preventDefault();
      this.set(name, value, input, row.querySelector('.err'));
    });
    row.querySelector('.delete').addEventListener('click', () => this.remove(name));
    return row;
  }

  async set(name, current, input, error) {
    const [value, problem] = typedValue(input.value, current);
    error.textContent = problem;
    error.hidden = !problem;
    input.toggleAttribute('aria-invalid', Boolean(problem));
    if (problem || !this.session) return;
    try {
      await this.session.rosapi('set_param', { name, value: JSON.stringify(value) });
      this.say(`Set ${name} = ${JSON.stringify(value)}.`, 'ok');
      this.refresh();
    } catch (err) {
      error.textContent = `Not set: ${err.message}`;
      error.hidden = false;
    }
  }

  // Deleting takes one click; Undo sets the value it had just before back.
  async remove(name) {
    if (!this.session) return;
    try {
      const { value } = await this.session.rosapi('get_param', { name });
      await this.session.rosapi('delete_param', { name });
      this.say(`Deleted ${name}.`, 'ok', () => this.restore(name, value));
      this.refresh();
    } catch (err) {
      this.say(`Could not delete ${name}: ${err.message}`, 'error');
    }
  }

  async restore(name, value) {
    if (!this.session) return;
    try {
      await this.session.rosapi('set_param', { name, value });
      this.say(`Restored ${name} = ${value}.`, 'ok');
      this.refresh();
    } catch (err) {
      this.say(`Could not restore ${name}: ${err.message}`, 'error');
    }
  }

  // What the last Set or Delete did (the panel's status line is for listing failures, and cleared by the next
  // listing); with an Undo button when given one.
  say(text, kind, undo) {
    this.result.className = `param-status ${kind}`;
    this.result.textContent = text;
    if (!undo) return;
    const button = document.createElement('button');
    button.type = 'button';
    button.className = 'undo';
    button.textContent = 'Undo';
    button.addEventListener('click', undo);
    this.result.append(' ', button);
  }
}

// [value, error]: the text as a value of the current value's type (a string parameter takes the text as is).
export function typedValue(text, current) {
  if (typeof current === 'string') return [text, ''];
  let value;
  try {
    value = JSON.parse(text.trim());
  } catch {
    return [undefined, `“${text.trim()}” is not ${describe(current)}.`];
  }
  if (current !== undefined && kind(value) !== kind(current)) {
    return [undefined, `${name(kind(current))} expected (the parameter holds ${describe(current)}).`];
  }
  return [value, ''];
}

function kind(value) {
  if (Array.isArray(value)) return 'list';
  if (value === null) return 'null';
  return typeof value;
}

function name(k) {
  return { number: 'A number', boolean: 'true or false', list: 'A JSON list', object: 'A JSON object' }[k] ?? k;
}

function describe(value) {
  return { number: 'a number', boolean: 'true or false', list: 'a list', object: 'a dictionary' }[kind(value)]
    ?? 'valid JSON';
}
