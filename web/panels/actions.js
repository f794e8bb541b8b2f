// Actions (actionlib's axclient): every action server (a namespace with the five topics goal, cancel, status,
// feedback and result); for the one chosen, a form made from its goal type (messages.js's, as Publish makes
// one), with Send goal after the fields; Send sends a goal, whose status, latest feedback and result are shown
// live; Cancel cancels it. The address keeps the server (?action=/fibonacci).
import { readAddress, keepInAddress } from '../address.js';
import { messageForm, messageTree } from '../parts/messages.js';
import { ListPanel, fillSelect } from '../parts/panel.js';

const ACTION_PARAM = 'action';
const REFRESH_MS = 3000;
const MAX_GOALS_SHOWN = 10;
// actionlib_msgs/GoalStatus's codes
const STATUS = ['pending', 'active', 'preempted', 'succeeded', 'aborted', 'rejected', 'preempting', 'recalling',
  'recalled', 'lost'];
const DONE = new Set([2, 3, 4, 5, 8, 9]);

export class ActionsPanel extends ListPanel {
  constructor(root, page) {
    super(root, page, 'Could not list the action servers');
    root.innerHTML = `
      <p class="hint">actionlib (axclient): send a goal to an action server, see its feedback, status and result,
        cancel it. <span class="action-count muted"></span></p>
      <p class="panel-status error" role="status"></p>
      <form class="action-send" novalidate>
        <div class="row"><label for="action-server" class="sr-only">Action server</label>
          <select id="action-server" class="action-server"></select></div>
        <p class="action-info muted" role="status"></p>
        <div class="action-form service-form"></div>
        <div class="row"><button type="submit" class="primary action-go">Send goal</button></div>
      </form>
      <p class="action-status" role="status" aria-live="polite"></p>
      <ol class="action-goals"></ol>`;
    this.select = root.querySelector('select.action-server');
    this.formArea = root.querySelector('.action-form');
    this.info = root.querySelector('.action-info');
    this.goalsList = root.querySelector('.action-goals');
    this.statusLine = root.querySelector('.action-status');
    [this.wanted] = readAddress(ACTION_PARAM);
    this.chosen = null;  // { server, action, client, statusSub }
    this.select.addEventListener('change', () => {
      this.wanted = this.select.value;
      keepInAddress(ACTION_PARAM, this.wanted ? [this.wanted] : []);
      this.choose();
    });
    root.querySelector('form').addEventListener('submit', event => {
      event.preventDefault();
      this.sendGoal();
    });
  }

  async load(session) {
    return [...(await session.rosapi('action_servers')).action_servers].sort();
  }

  render(servers) {
    this.root.querySelector('.action-count').textContent = servers.length ? `(${servers.length})`
      : '(none now: an actionlib server is found by its five topics, e.g. /move_base/goal … /move_base/result)';
    const choices = servers.map(s => [s, s]);
    if (this.wanted && !servers.includes(this.wanted)) choices.push([this.wanted, `${this.wanted} (not running)`]);
    fillSelect(this.select, 'Choose an action server…', choices);
    if (this.wanted) this.select.value = this.wanted;
    if (this.select.value !== (this.chosen?.server ?? '') || (this.chosen && !this.chosen.action)) this.choose();
  }

  // While shown, the list is asked for again every few seconds (a node started later appears).
  show(visible) {
    super.show(visible);
    clearInterval(this.timer);
    this.timer = visible ? setInterval(() => this.refresh(), REFRESH_MS) : null;
  }

  attach(session) {
    this.shown = null;  // (render again: the client is made anew on this session)
    super.attach(session);
  }

  detach() {
    this.drop();
    super.detach();
  }

  drop() {
    this.chosen?.client?.close();
    this.chosen?.statusSub?.close();
    this.chosen = null;
  }

  // The server's action type, from its goal topic (<ns>/goal is <pkg>/<Name>ActionGoal); its goal's form.
  async choose() {
    this.drop();
    this.formArea.replaceChildren();
    this.info.textContent = '';
    const server = this.select.value;
    const session = this.session;
    if (!server || !session) return;
    const chosen = { server, action: null };
    this.chosen = chosen;
    try {
      const { type } = await session.rosapi('topic_type', { topic: `${server}/goal` });
      if (this.chosen !== chosen) return;
      if (!/ActionGoal$/.test(type)) {
        this.info.textContent = `${server}/goal has no action type yet (${type || 'none'}).`;
        return;
      }
      const action = type.replace(/Goal$/, '');  // actionlib/TestAction
      const goalType = type.replace(/ActionGoal$/, 'Goal');  // actionlib/TestGoal
      const { typedefs } = await session.rosapi('message_details', { type: goalType });
      if (this.chosen !== chosen) return;
      chosen.action = action;
      chosen.form = messageForm(typedefs);
      chosen.client = session.actionClient(server, action);
      chosen.statusSub = session.subscribe(`${server}/status`, 'actionlib_msgs/GoalStatusArray', message => {
        if (this.chosen !== chosen) return;
        const active = message.status_list.filter(status => !DONE.has(status.status)).length;
        this.info.textContent = `${action} · server alive: ${active} goal${active === 1 ? '' : 's'} in progress.`;
        this.info.dataset.alive = 'true';
      }, { throttle_rate: 500, queue_length: 1 });
      this.info.textContent = `${action} · waiting for the server's status…`;
      delete this.info.dataset.alive;
      const heading = document.createElement('p');
      heading.className = 'muted';
      heading.innerHTML = 'Goal <code></code>';
      heading.lastChild.textContent = goalType;
      this.formArea.replaceChildren(heading, chosen.form.element);
    } catch (error) {
      if (this.chosen === chosen) this.info.textContent = `Could not read ${server}'s type: ${error.message}`;
    }
  }

  sendGoal() {
    const chosen = this.chosen;
    if (!this.session) return this.say('Not connected.', 'error');
    if (!chosen?.client) return this.say('Choose an action server first.', 'error');
    const goal = chosen.form.read();
    if (goal === null) return this.say('Not sent: fix the highlighted fields.', 'error');
    const item = document.createElement('li');
    item.className = 'action-goal';
    item.innerHTML = `<div class="row"><span class="goal-state" data-status="">sent</span>
        <code class="goal-what"></code><button type="button" class="goal-cancel">Cancel</button></div>
      <div class="goal-feedback"><span class="muted">Feedback:</span> <span class="goal-feedback-tree muted">none yet</span></div>
      <div class="goal-result" hidden><span class="muted">Result:</span> <span class="goal-result-tree"></span></div>
      <p class="goal-text muted"></p>`;
    item.querySelector('.goal-what').textContent = `${chosen.server} ${JSON.stringify(goal)}`;
    const state = item.querySelector('.goal-state');
    const cancel = item.querySelector('.goal-cancel');
    const feedbackCount = { n: 0 };
    let ended = false;  // its end is shown: a status from before it, come late by another topic, changes nothing
    const handle = chosen.client.send(goal, {
      onStatus: status => {
        if (ended && !DONE.has(status.status)) return;
        ended = DONE.has(status.status);
        state.textContent = STATUS[status.status] ?? `status ${status.status}`;
        state.dataset.status = STATUS[status.status] ?? '';
        item.querySelector('.goal-text').textContent = status.text || '';
        if (DONE.has(status.status)) cancel.hidden = true;
      },
      onFeedback: feedback => {
        feedbackCount.n += 1;
        const tree = item.querySelector('.goal-feedback-tree');
        tree.className = 'goal-feedback-tree';
        tree.replaceChildren(messageTree(feedback));
        item.querySelector('.goal-feedback > .muted').textContent = `Feedback (${feedbackCount.n}):`;
      },
      onResult: result => {
        const box = item.querySelector('.goal-result');
        box.hidden = false;
        box.querySelector('.goal-result-tree').replaceChildren(messageTree(result));
        cancel.hidden = true;
      },
    });
    item.dataset.goal = handle.id;
    cancel.addEventListener('click', () => {
      handle.cancel();
      state.textContent = 'cancel sent';
    });
    this.goalsList.prepend(item);
    while (this.goalsList.children.length > MAX_GOALS_SHOWN) this.goalsList.lastChild.remove();
    this.say(`Goal sent to ${chosen.server}.`, 'ok');
    return undefined;
  }

  say(text, kind) {
    this.statusLine.textContent = text;
    this.statusLine.className = `action-status ${kind}`;
  }
}
