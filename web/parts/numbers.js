// Numbers typed by people, read from the page's number fields; a bad one is flagged under its field (the element
// whose id is the field's id + '-err').

// Accepts "1.5", "-2", ".5", "1e-3" and a decimal comma ("1,5", what phone keypads in many locales type); anything
// else is an inline error on the field. Returns the number, null for a blank optional field, or undefined when
// invalid.
function readNumber(input, { optional = false } = {}) {
  const text = input.value.trim().replace(',', '.');
  let error = '';
  if (text === '') {
    if (!optional) error = 'Enter a number.';
  } else if (!/^[+-]?(\d+\.?\d*|\.\d+)(e[+-]?\d+)?$/i.test(text) || !Number.isFinite(Number(text))) {
    error = `“${input.value.trim()}” is not a number.`;
  }
  const out = document.getElementById(`${input.id}-err`);
  out.textContent = error;
  out.hidden = !error;
  input.toggleAttribute('aria-invalid', Boolean(error));
  if (error) return undefined;
  return text === '' ? null : Number(text);
}

// Reads several fields at once (so every bad one is marked); undefined if any is invalid.
export function readNumbers(ids, options) {
  const values = ids.map(id => readNumber(document.getElementById(id), options));
  return values.includes(undefined) ? undefined : values;
}

// The markup of one number field, with the place for its error; label is HTML (e.g. 'θ <span class="unit">rad</span>').
export function numberField(id, label, { value = '', placeholder = '' } = {}) {
  return `<div class="field"><label for="${id}">${label}</label>
    <input id="${id}" inputmode="decimal" autocomplete="off" value="${value}" placeholder="${placeholder}"
      aria-describedby="${id}-err">
    <p id="${id}-err" class="err" hidden></p></div>`;
}
