// The world's services: Clear trails (/clear), Reset (/reset), Spawn (/spawn), Teleport (the driven turtle's
// teleport_absolute); what they did, or their error, on the panel's status line. Clear and Reset ask first.
import WORLD from '../world-constants.js';
import { Panel } from '../parts/panel.js';
import { numberField, readNumbers } from '../parts/numbers.js';
import { confirmFirst } from '../parts/confirm.js';

const SPAWN_MARGIN_M = 1;  // keeps random turtles off the walls

export class WorldToolsPanel extends Panel {
  constructor(root, page) {
    super(root, page);
    const first = WORLD.first_turtle;
    root.insertAdjacentHTML('beforeend', `
      <div class="buttons">
        <button id="clear" type="button">Clear trails</button>
        <button id="reset" type="button">Reset</button>
      </div>
      <form id="spawn-form" class="fields" novalidate>
        <fieldset>
          <legend>Spawn a turtle <small>(blank = random)</small></legend>
          ${numberField('spawn-x', 'x', { placeholder: 'random' })}
          ${numberField('spawn-y', 'y', { placeholder: 'random' })}
          ${numberField('spawn-theta', 'θ <span class="unit">rad</span>', { placeholder: 'random' })}
          <div class="field wide"><label for="spawn-name">name</label>
            <input id="spawn-name" autocomplete="off" autocapitalize="none" spellcheck="false" placeholder="auto"></div>
          <button id="spawn" type="submit">Spawn</button>
        </fieldset>
      </form>
      <form id="teleport-form" class="fields" novalidate>
        <fieldset>
          <legend>Teleport <span class="driven-turtle"></span></legend>
          ${numberField('tp-x', 'x', { value: first.x.toFixed(3) })}
          ${numberField('tp-y', 'y', { value: first.y.toFixed(3) })}
          ${numberField('tp-theta', 'θ <span class="unit">rad</span>', { value: first.theta })}
          <button id="teleport" type="submit">Teleport</button>
        </fieldset>
      </form>
      <p id="service-status" class="status" role="status" aria-live="polite"></p>`);
    this.$ = selector => root.querySelector(selector);
    this.drive.onChange(() => {
      this.$('.driven-turtle').textContent = this.drive.turtle() ?? '(drive a turtle)';
    });
    this.$('#clear').addEventListener('click', () => this.clear());
    this.$('#reset').addEventListener('click', () => this.reset());
    this.$('#spawn-form').addEventListener('submit', event => {
      event.preventDefault();
      this.spawn();
    });
    this.$('#teleport-form').addEventListener('submit', event => {
      event.preventDefault();
      this.teleport();
    });
  }

  get drive() {
    return this.page.panels.get('drive');
  }

  get world() {
    return this.page.panels.get('world');
  }

  say(text, kind = 'info') {
    const out = this.$('#service-status');
    out.textContent = text;
    out.className = `status ${kind}`;
  }

  // Calls a service; done(response) says what it did.
  async call(name, type, args, done) {
    if (!this.session) {
      this.say(`Not connected: ${name} was not called.`, 'error');
      return;
    }
    this.say(`Calling ${name}…`);
    try {
      this.say(done(await this.session.call(name, type, args)), 'ok');
      this.world.discover();
    } catch (error) {
      this.say(`${name} failed: ${error.message || 'the service reported an error'}`, 'error');
    }
  }

  async clear() {
    if (!await confirmFirst(this.$('#clear'), 'Clear every trail? This cannot be undone.', 'Clear trails')) return;
    this.call('/clear', 'std_srvs/Empty', {}, () => {
      this.world.clearTrails();
      return 'Trails cleared.';
    });
  }

  async reset() {
    const question = 'Reset the world? Every turtle but a new turtle1 is removed, with the trails. ' +
      'This cannot be undone.';
    if (!await confirmFirst(this.$('#reset'), question, 'Reset')) return;
    this.call('/reset', 'std_srvs/Empty', {}, () => {
      this.world.forgetTurtles();
      return 'World reset: turtle1 is back in the centre.';
    });
  }

  spawn() {
    const values = readNumbers(['spawn-x', 'spawn-y', 'spawn-theta'], { optional: true });
    if (!values) return;
    const random = (lo, hi) => lo + Math.random() * (hi - lo);
    const [x, y, theta] = values;
    const args = {
      x: x ?? random(SPAWN_MARGIN_M, WORLD.size_m - SPAWN_MARGIN_M),
      y: y ?? random(SPAWN_MARGIN_M, WORLD.size_m - SPAWN_MARGIN_M),
      theta: theta ?? random(-Math.PI, Math.PI),
      name: this.$('#spawn-name').value.trim(),
    };
    this.call('/spawn', 'turtlesim/Spawn', args,
      result => `Spawned ${result.name} at (${args.x.toFixed(2)}, ${args.y.toFixed(2)}).`);
  }

  teleport() {
    const values = readNumbers(['tp-x', 'tp-y', 'tp-theta']);
    if (!values) return;
    const [x, y, theta] = values;
    const name = this.drive.turtle();
    if (!name) {
      this.say(`${this.drive.topic} is not a turtle's cmd_vel: choose a turtle to teleport under Drive.`, 'error');
      return;
    }
    this.call(`/${name}/teleport_absolute`, 'turtlesim/TeleportAbsolute', { x, y, theta },
      () => `Teleported ${name} to (${x}, ${y}, ${theta}).`);
  }
}
