// Reconfigure (rqt_reconfigure): every node that serves dynamic_reconfigure (a <node>/set_parameters service of
// type dynamic_reconfigure/Reconfigure); for the node chosen, a form made from its latched
// <node>/parameter_descriptions (groups, each parameter's type, range, default and enum), kept up to date by
// <node>/parameter_updates. An edit calls <node>/set_parameters with that one parameter, and the form shows the
// configuration the node answers: a value it clamped or changed reads as the node has it, and says so under the
// field. The address keeps the node (?reconfigure=/camera).
import { readAddress, keepInAddress } from '../address.js';
import { ListPanel, fillSelect } from '../parts/panel.js';

const NODE_PARAM = 'reconfigure';
const SERVICE_TYPE = 'dynamic_reconfigure/Reconfigure';
const LISTS = { bool: 'bools', int: 'ints', str: 'strs', double: 'doubles' };
const REFRESH_MS = 3000;
const SLIDER_SPAN = 1e9;  // a range wider than this (int32's full range: "no range" in a .cfg) has no slider

export class ReconfigurePanel extends ListPanel {
  constructor(root, page) {
    super(root, page, 'Could not list the reconfigurable nodes');
    root.innerHTML = `
      <p class="hint">dynamic_reconfigure (rqt_reconfigure): a node's parameters, changed live; the form shows what
        the node answers. <span class="reconfigure-count muted"></span></p>
      <p class="panel-status error" role="status"></p>
      <div class="row"><label for="reconfigure-node" class="sr-only">Node</label>
        <select id="reconfigure-node" class="reconfigure-node"></select></div>
      <p class="reconfigure-status" role="status" aria-live="polite"></p>
      <div class="reconfigure-form"></div>`;
    this.select = root.querySelector('select.reconfigure-node');
    this.formArea = root.querySelector('.reconfigure-form');
    this.statusLine = root.querySelector('.reconfigure-status');
    // The edits go one at a time, in the order they were made: the bridge runs service calls side by side, and
    // a quick second edit of a field could reach the node first and be undone by the first.
    this.edits = Promise.resolve();
    [this.wanted] = readAddress(NODE_PARAM);
    this.subscriptions = [];
    this.fields = new Map();  // parameter name -> { type, set(value), note(text, kind) }
    this.select.addEventListener('change', () => {
      this.wanted = this.select.value;
      keepInAddress(NODE_PARAM, this.wanted ? [this.wanted] : []);
      this.open();
    });
  }

  async load(session) {
    const { services } = await session.rosapi('services_for_type', { type: SERVICE_TYPE });
    return services.filter(name => name.endsWith('/set_parameters'))
      .map(name => name.slice(0, -'/set_parameters'.length)).sort();
  }

  render(nodes) {
    this.root.querySelector('.reconfigure-count').textContent = nodes.length ? `(${nodes.length})`
      : '(none now: a node serves it with a dynamic_reconfigure Server; `rosrun dynamic_reconfigure dynparam list` ' +
        'lists the same)';
    const choices = nodes.map(n => [n, n]);
    if (this.wanted && !nodes.includes(this.wanted)) choices.push([this.wanted, `${this.wanted} (not serving)`]);
    fillSelect(this.select, 'Choose a node…', choices);
    if (this.wanted) this.select.value = this.wanted;
    if (this.select.value !== this.openNode) this.open();
  }

  // While shown, the list is asked for again every few seconds (a node started later appears).
  show(visible) {
    super.show(visible);
    clearInterval(this.timer);
    this.timer = visible ? setInterval(() => this.refresh(), REFRESH_MS) : null;
  }

  attach(session) {
    this.openNode = null;
    this.edits = Promise.resolve();  // (an edit left on the old session never settles)
    this.shown = null;  // (render again: the node's topics are subscribed anew on this session)
    super.attach(session);
  }

  detach() {
    this.close();
    this.openNode = null;
    super.detach();
  }

  close() {
    for (const subscription of this.subscriptions) subscription.close();
    this.subscriptions = [];
  }

  // Subscribes to the chosen node's description and updates; the form is made when the description comes.
  open() {
    this.close();
    this.formArea.replaceChildren();
    this.fields.clear();
    this.say('', '');
    const node = this.select.value;
    this.openNode = node;
    if (!node || !this.session) return;
    this.say(`Waiting for ${node}/parameter_descriptions…`, 'info');
    let config = null;
    this.subscriptions.push(
      this.session.subscribe(`${node}/parameter_descriptions`, 'dynamic_reconfigure/ConfigDescription', description => {
        if (node !== this.openNode) return;
        this.build(node, description);
        this.say('', '');
        if (config) this.showConfig(config);
      }),
      this.session.subscribe(`${node}/parameter_updates`, 'dynamic_reconfigure/Config', update => {
        if (node !== this.openNode) return;
        config = update;
        this.showConfig(update);
      }));
  }

  build(node, description) {
    const { groups } = description;
    const bound = (config, name) => valuesOf(config).get(name);
    const root = groups.find(group => group.id === 0) ?? groups[0];
    if (!root) {
      this.formArea.textContent = `${node} describes no parameters.`;
      return;
    }
    const make = group => {
      const box = document.createElement(group.type === 'collapse' ? 'details' : 'section');
      box.className = 'reconfigure-group';
      box.dataset.group = group.name;
      if (group.type === 'collapse') box.open = true;
      if (group !== root) {
        const heading = document.createElement(group.type === 'collapse' ? 'summary' : 'h3');
        heading.textContent = group.name.replace(/_/g, ' ');
        box.append(heading);
      }
      const fields = document.createElement('div');
      fields.className = 'reconfigure-fields';
      for (const param of group.parameters) {
        const field = this.field(node, param, {
          min: bound(description.min, param.name), max: bound(description.max, param.name),
          dflt: bound(description.dflt, param.name),
        });
        this.fields.set(param.name, field);
        fields.append(field.element);
      }
      box.append(fields);
      for (const child of groups.filter(g => g.parent === group.id && g.id !== group.id)) box.append(make(child));
      return box;
    };
    this.fields.clear();
    this.formArea.replaceChildren(make(root));
  }

  // One parameter's control: a select for an enum, a checkbox for a bool, a slider and a number for a number
  // with a range, a text field otherwise. Each edit sends the value at once.
  field(node, param, { min, max, dflt }) {
    const { name, type } = param;
    const element = document.createElement('div');
    element.className = 'reconfigure-field';
    element.dataset.param = name;
    const id = `reconfigure-${name}`;
    element.innerHTML = `<label for="${id}"><span class="name"></span> <span class="unit"></span></label>
      <div class="controls"></div><p class="err" hidden></p>`;
    element.querySelector('.name').textContent = name;
    const whole = type === 'int' && min <= -(2 ** 31) && max >= 2 ** 31 - 1;  // a .cfg's "no range" for an int
    const rangeText = (type === 'int' && !whole) || type === 'double'
      ? ` ${finite(min) ? min : '−∞'} … ${finite(max) ? max : '∞'}` : '';
    element.querySelector('.unit').textContent = `${type}${rangeText}`;
    element.title = [param.description, dflt !== undefined ? `default ${dflt}` : ''].filter(Boolean).join(' · ');
    const controls = element.querySelector('.controls');
    const note = element.querySelector('.err');
    const say = (text, kind = 'error') => {
      note.textContent = text;
      note.className = `err ${kind}`;
      note.hidden = !text;
    };
    const send = value => this.send(node, name, type, value, say, field);
    const enumeration = enumOf(param.edit_method);
    let set;
    if (enumeration) {
      const select = document.createElement('select');
      select.id = id;
      for (const constant of enumeration) {
        const option = new Option(`${constant.name} (${constant.value})`, String(constant.value));
        option.title = constant.description ?? '';
        select.append(option);
      }
      select.addEventListener('change', () => send(type === 'str' ? select.value : Number(select.value)));
      controls.append(select);
      set = value => { select.value = String(value); };
    } else if (type === 'bool') {
      const check = document.createElement('label');  // (the box and its value: one touch target)
      check.className = 'check';
      check.innerHTML = '<input type="checkbox"> <span></span>';
      const box = check.firstChild;
      box.id = id;
      const said = check.lastChild;
      box.addEventListener('change', () => send(box.checked));
      controls.append(check);
      set = value => {
        box.checked = Boolean(value);
        said.textContent = box.checked ? 'true' : 'false';
      };
    } else if (type === 'str') {
      const input = document.createElement('input');
      Object.assign(input, { id, autocomplete: 'off', spellcheck: false });
      input.addEventListener('change', () => send(input.value));
      controls.append(input);
      // (not under the person typing, unless it answers what the field holds)
      set = (value, sent) => {
        if (document.activeElement !== input || input.value === sent) input.value = value;
      };
    } else {
      const number = document.createElement('input');
      Object.assign(number, { id, inputMode: type === 'int' ? 'numeric' : 'decimal', autocomplete: 'off' });
      number.className = 'reconfigure-number';
      let slider = null;
      if (finite(min) && finite(max) && max - min <= SLIDER_SPAN && max > min) {
        slider = document.createElement('input');
        Object.assign(slider, { type: 'range', min, max, step: type === 'int' ? 1 : (max - min) / 1000 });
        slider.setAttribute('aria-label', `${name} slider`);
        slider.addEventListener('input', () => { number.value = slider.value; });
        slider.addEventListener('change', () => send(Number(slider.value)));
        controls.append(slider);
      }
      controls.append(number);
      number.addEventListener('change', () => {
        const text = number.value.trim().replace(',', '.');
        const value = Number(text);
        if (text === '' || !Number.isFinite(value)) return say(`“${number.value}” is not a number: nothing sent.`);
        if (type === 'int' && !Number.isInteger(value)) return say('A whole number: nothing sent.');
        return send(value);
      });
      set = (value, sent) => {
        const typed = Number(number.value.trim().replace(',', '.'));
        if (document.activeElement !== number || typed === sent) number.value = value === null ? '' : String(value);
        if (slider && value !== null) slider.value = String(value);
      };
    }
    const field = { element, type, set, say, min, max };
    return field;
  }

  // Sends one parameter; the node's answer is its whole configuration, which the form then shows.
  async send(node, name, type, value, say, field) {
    if (!this.session) return say('Not connected: nothing sent.');
    const config = { bools: [], ints: [], strs: [], doubles: [], groups: [] };
    config[LISTS[type]].push({ name, value });
    const range = outside(value, field.min, field.max);
    say(range ? `${value} is ${range}: sent, the node decides…` : 'Sending…', range ? 'warn' : 'info');
    try {
      const session = this.session;
      const call = this.edits.then(() => session.call(`${node}/set_parameters`, SERVICE_TYPE, { config }));
      this.edits = call.catch(() => {});
      const answer = await call;
      if (node !== this.openNode) return;
      this.showConfig(answer.config);
      const got = valuesOf(answer.config).get(name);
      field.set(got, value);  // the answer to this field's own edit, where the person still is (Enter)
      if (got === value) say('', '');
      else say(`Asked ${value}; ${node} set ${got}${range ? ` (${range})` : ''}.`, 'warn');
      this.say(`${node} answered: ${name} = ${got}.`, 'ok');
    } catch (error) {
      say(`Not set: ${error.message}`);
    }
  }

  // The node's configuration in the form; a text or number field being typed in is left as it is.
  showConfig(config) {
    for (const [name, value] of valuesOf(config)) this.fields.get(name)?.set(value);
  }

  say(text, kind) {
    this.statusLine.textContent = text;
    this.statusLine.className = `reconfigure-status ${kind}`;
  }
}

// name -> value of a dynamic_reconfigure/Config (NaN and infinities come as null over the bridge).
function valuesOf(config) {
  const values = new Map();
  for (const list of Object.values(LISTS)) for (const { name, value } of config?.[list] ?? []) values.set(name, value);
  return values;
}

function finite(value) {
  return typeof value === 'number' && Number.isFinite(value);
}

function outside(value, min, max) {
  if (typeof value !== 'number') return '';
  if (finite(max) && value > max) return `above the maximum ${max}`;
  if (finite(min) && value < min) return `below the minimum ${min}`;
  return '';
}

// The constants of an enum parameter ([{name, value, description}]), or null. dynamic_reconfigure writes the
// edit_method as a Python literal (a dict's repr: single quotes, True/False/None), which rqt_reconfigure eval()s;
// here it is read by a small parser of those literals, never run.
export function enumOf(editMethod) {
  if (!editMethod) return null;
  try {
    const value = pythonLiteral(editMethod);
    return Array.isArray(value?.enum) && value.enum.length ? value.enum : null;
  } catch {
    return null;
  }
}

export function pythonLiteral(text) {
  let i = 0;
  const space = () => { while (/\s/.test(text[i])) i++; };
  const fail = () => { throw new Error(`not a Python literal at ${i}: ${text.slice(i, i + 20)}`); };
  const value = () => {
    space();
    const c = text[i];
    if (c === '{' || c === '[' || c === '(') {
      const close = { '{': '}', '[': ']', '(': ')' }[c];
      i++;
      const items = [];
      const entries = [];
      for (;;) {
        space();
        if (text[i] === close) { i++; break; }
        const item = value();
        space();
        if (c === '{') {
          if (text[i++] !== ':') fail();
          entries.push([item, value()]);
        } else {
          items.push(item);
        }
        space();
        if (text[i] === ',') i++;
        else if (text[i] !== close) fail();
      }
      return c === '{' ? Object.fromEntries(entries) : items;
    }
    if (c === "'" || c === '"') {
      i++;
      let out = '';
      while (text[i] !== c) {
        if (i >= text.length) fail();
        if (text[i] === '\\') {
          i++;
          out += { n: '\n', t: '\t', r: '\r', '\\': '\\', "'": "'", '"': '"' }[text[i]] ?? `\\${text[i]}`;
        } else {
          out += text[i];
        }
        i++;
      }
      i++;
      return out;
    }
    const word = /^(True|False|None|[-+]?(?:inf|nan|\d[\d_]*\.?\d*(?:e[-+]?\d+)?|\.\d+(?:e[-+]?\d+)?))/i
      .exec(text.slice(i));
    if (!word) fail();
    i += word[0].length;
    return { True: true, False: false, None: null }[word[0]] ?? Number(word[0].replace(/_/g, '').replace(/inf$/i, 'Infinity'));
  };
  const result = value();
  space();
  if (i !== text.length) fail();
  return result;
}
