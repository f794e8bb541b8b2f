// Message definitions and values as a person reads them: the text `rosmsg show` prints, a collapsible tree of a
// live message, and a form generated from a definition (for service requests). Definitions come from rosapi's
// message_details / service_request_details: a list of typedefs {type, fieldnames, fieldtypes, fieldarraylen,
// constnames, constvalues}, the first one the root.

const PRIMITIVES = new Set(['bool', 'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64',
  'float32', 'float64', 'string', 'time', 'duration', 'byte', 'char']);
const INTEGERS = /^u?int(8|16|32|64)$|^byte$|^char$/;
const BYTES = new Set(['int8', 'uint8', 'byte', 'char']);
const LONGEST_LEAF = 200;  // characters of a text shown in a message tree

export function typedefMap(typedefs) {
  return new Map(typedefs.map(t => [t.type, t]));
}

function arraySuffix(length) {
  return length === -1 ? '' : length === 0 ? '[]' : `[${length}]`;
}

// The definition as `rosmsg show` prints it: constants, then fields, nested types indented.
export function definitionText(typedefs, type = typedefs[0]?.type) {
  const byType = typedefMap(typedefs);
  const lines = [];
  const walk = (typeName, indent) => {
    const def = byType.get(typeName);
    if (!def) return;
    (def.constnames || []).forEach((name, i) => lines.push(`${indent}${name}=${def.constvalues[i]}`));
    def.fieldnames.forEach((name, i) => {
      const fieldType = def.fieldtypes[i];
      lines.push(`${indent}${fieldType}${arraySuffix(def.fieldarraylen[i])} ${name}`);
      if (!PRIMITIVES.has(fieldType)) walk(fieldType, `${indent}  `);
    });
  };
  walk(type, '');
  return lines.join('\n');
}

// The fields that may make a message of this type megabytes: its variable-length arrays of bytes (a picture's,
// a map's or a cloud's data), nested ones included, as e.g. ['data: int8[]', 'images[].data: uint8[]'].
export function bulkArrays(typedefs, type = typedefs[0]?.type) {
  const byType = typedefMap(typedefs);
  const found = [];
  const walk = (typeName, prefix) => {
    const def = byType.get(typeName);
    def?.fieldnames.forEach((name, i) => {
      const [fieldType, length] = [def.fieldtypes[i], def.fieldarraylen[i]];
      if (length === 0 && BYTES.has(fieldType)) found.push(`${prefix}${name}: ${fieldType}[]`);
      else if (!PRIMITIVES.has(fieldType)) walk(fieldType, `${prefix}${name}${length === -1 ? '' : '[]'}.`);
    });
  };
  walk(type, '');
  return found;
}

// A live message as nested <details>; leaves show `name: value`. onLeaf(path, element) lets a panel make
// numeric leaves clickable (path: e.g. ['pose', 'position', 'x']). `open` keeps the branches a person opened.
// `leaves`, if given, gets each leaf's value element in the order of treeShape's texts, so that the next message
// of the same shape can be shown by changing those texts alone.
export function messageTree(value, { onLeaf, open = new Set(), path = [], leaves } = {}) {
  if (!isBranch(value)) {
    const leaf = document.createElement('span');
    leaf.textContent = leafText(value);
    return leaf;
  }
  const list = document.createElement('ul');
  list.className = 'tree';
  const entries = Array.isArray(value) ? value.map((v, i) => [String(i), v]) : Object.entries(value);
  const shown = Array.isArray(value) ? entries.slice(0, 64) : entries;  // a long array stays readable
  for (const [key, child] of shown) {
    const item = document.createElement('li');
    const childPath = [...path, key];
    if (isBranch(child)) {
      const details = document.createElement('details');
      const id = childPath.join('.');
      details.open = open.has(id) || childPath.length < 2;
      details.addEventListener('toggle', () => (details.open ? open.add(id) : open.delete(id)));
      const summary = document.createElement('summary');
      summary.textContent = Array.isArray(child) ? `${key} [${child.length}]` : key;
      details.append(summary, messageTree(child, { onLeaf, open, path: childPath, leaves }));
      item.append(details);
    } else {
      item.innerHTML = '<span class="key"></span>: <span class="value"></span>';
      item.firstChild.textContent = key;
      item.lastChild.textContent = leafText(child);
      leaves?.push(item.lastChild);
      if (onLeaf) onLeaf(childPath, item, child);
    }
    list.append(item);
  }
  if (shown.length < entries.length) {
    const more = document.createElement('li');
    more.className = 'muted';
    more.textContent = `… ${entries.length - shown.length} more`;
    list.append(more);
  }
  return list;
}

// What messageTree would show of a message: its shape (keys, nesting, array lengths: the tree's elements) and the
// texts of its leaves, in the order of messageTree's `leaves`.
export function treeShape(value) {
  const parts = [];
  const texts = [];
  const walk = node => {
    const entries = Array.isArray(node) ? node.map((v, i) => [String(i), v]) : Object.entries(node);
    const shown = Array.isArray(node) ? entries.slice(0, 64) : entries;
    for (const [key, child] of shown) {
      if (isBranch(child)) {
        parts.push(Array.isArray(child) ? `${key}[${child.length}]{` : `${key}{`);
        walk(child);
        parts.push('}');
      } else {
        parts.push(key);
        texts.push(leafText(child));
      }
    }
  };
  if (isBranch(value)) walk(value);
  else texts.push(leafText(value));
  return { shape: JSON.stringify(parts), texts };
}

// Binary arrays (a picture's data as CBOR gives them) are leaves, not branches of a million bytes.
function isBranch(value) {
  return value !== null && typeof value === 'object' && !ArrayBuffer.isView(value);
}

// A long text (a picture's data in base64, as JSON gives it) is cut: the tree is a summary, not a dump.
function leafText(value) {
  if (value === null) return 'null';
  if (ArrayBuffer.isView(value)) return `(${value.byteLength} bytes)`;
  const text = String(value);
  return text.length > LONGEST_LEAF ? `${text.slice(0, LONGEST_LEAF)}… (${text.length} characters)` : text;
}

// A form for one message type: an input per primitive field (nested types as fieldsets, arrays as JSON text),
// with the type's defaults. read() returns the message, or null after marking every bad field inline.
export function messageForm(typedefs, type = typedefs[0]?.type) {
  const byType = typedefMap(typedefs);
  const readers = [];
  const build = (typeName, prefix) => {
    const box = document.createElement('div');
    box.className = 'fields';
    const def = byType.get(typeName);
    if (!def) return { box, read: () => ({}) };
    const parts = def.fieldnames.map((name, i) => {
      const fieldType = def.fieldtypes[i];
      const length = def.fieldarraylen[i];
      const id = `${prefix}${name}`;
      if (length === -1 && !PRIMITIVES.has(fieldType)) {
        const set = document.createElement('fieldset');
        const legend = document.createElement('legend');
        legend.textContent = `${name} (${fieldType})`;
        const inner = build(fieldType, `${id}.`);
        set.append(legend, inner.box);
        box.append(set);
        return [name, inner.read];
      }
      const field = fieldInput(id, name, fieldType, length, def.examples?.[i]);
      box.append(field.element);
      readers.push(field);
      return [name, field.read];
    });
    return { box, read: () => Object.fromEntries(parts.map(([name, read]) => [name, read()])) };
  };
  const root = build(type, '');
  return {
    element: root.box,
    read() {
      const message = root.read();
      return readers.some(field => field.invalid) ? null : message;
    },
  };
}

let fieldIds = 0;

function fieldInput(path, name, type, arrayLength, example) {
  const id = `field-${++fieldIds}`;
  const element = document.createElement('div');
  element.className = 'field';
  const kind = arrayLength === -1 ? type : `${type}${arraySuffix(arrayLength)}`;
  element.innerHTML = `<label for="${id}"></label><input id="${id}" autocomplete="off" spellcheck="false">
    <p class="err" hidden></p>`;
  const [label, input, error] = element.children;
  label.innerHTML = '<span></span> <span class="unit"></span>';
  label.firstChild.textContent = name;
  label.lastChild.textContent = kind;
  input.dataset.path = path;
  if (arrayLength !== -1 || type === 'time' || type === 'duration') {
    input.placeholder = arrayLength !== -1 ? '[ ] as JSON' : '{"secs": 0, "nsecs": 0}';
  } else if (type === 'bool') {
    input.placeholder = 'true or false';
  } else if (type !== 'string') {
    input.inputMode = 'decimal';
    input.placeholder = '0';
  }
  if (example !== undefined && example !== null && typeof example !== 'object') input.value = String(example);
  const field = {
    element,
    invalid: false,
    read() {
      const [value, problem] = parseField(input.value, type, arrayLength);
      field.invalid = Boolean(problem);
      error.textContent = problem;
      error.hidden = !problem;
      input.toggleAttribute('aria-invalid', field.invalid);
      return value;
    },
  };
  return field;
}

// [value, error text] for the text typed into a field of this type.
export function parseField(text, type, arrayLength = -1) {
  const trimmed = text.trim();
  if (arrayLength !== -1 || type === 'time' || type === 'duration') {
    if (trimmed === '') return [arrayLength !== -1 ? [] : { secs: 0, nsecs: 0 }, ''];
    try {
      return [JSON.parse(trimmed), ''];
    } catch {
      return [undefined, `“${trimmed}” is not JSON.`];
    }
  }
  if (type === 'string') return [text, ''];
  if (type === 'bool') {
    if (/^(|false|0)$/i.test(trimmed)) return [false, ''];
    if (/^(true|1)$/i.test(trimmed)) return [true, ''];
    return [undefined, 'Enter true or false.'];
  }
  if (trimmed === '') return [0, ''];
  const number = Number(trimmed.replace(',', '.'));
  if (!Number.isFinite(number)) return [undefined, `“${trimmed}” is not a number.`];
  if (INTEGERS.test(type) && !Number.isInteger(number)) return [undefined, `${type} takes a whole number.`];
  return [number, ''];
}
