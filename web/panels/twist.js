// The tutorial's panel: Linear X and Angular Z, and Publish sends one Twist on the topic driven (drive.js). The
// two numbers are also the top speeds of the keys and the joystick. The page's feedback list is shown here.
import { Panel } from '../parts/panel.js';
import { numberField, readNumbers } from '../parts/numbers.js';

const TUTORIAL_SPEED = 1.5;

export class TwistPanel extends Panel {
  constructor(root, page) {
    super(root, page);
    root.querySelector('h2').insertAdjacentHTML('beforeend', ' <small>on <code id="cmd-vel-name"></code></small>');
    root.insertAdjacentHTML('beforeend', `
      <form id="twist-form" class="fields" novalidate>
        ${numberField('linear', 'Linear X <span class="unit">m/s</span>', { value: TUTORIAL_SPEED })}
        ${numberField('angular', 'Angular Z <span class="unit">rad/s</span>', { value: TUTORIAL_SPEED })}
        <button id="publish" type="submit" class="primary">Publish</button>
      </form>`);
    root.append(page.feedback.element);
    const drive = page.panels.get('drive');
    drive.onChange(() => {
      root.querySelector('#cmd-vel-name').textContent = drive.topic;
    });
    root.querySelector('form').addEventListener('submit', event => {
      event.preventDefault();
      const speeds = this.speeds();
      if (!speeds) {
        page.feedback.add('Nothing published: fix the highlighted number.', 'error');
        return;
      }
      drive.report(drive.publish(speeds.linear, speeds.angular),
        `Published linear.x = ${speeds.linear}, angular.z = ${speeds.angular} on ${drive.topic}.`);
    });
  }

  // {linear, angular} as typed, or undefined (each bad field flagged).
  speeds() {
    const values = readNumbers(['linear', 'angular']);
    return values && { linear: values[0], angular: values[1] };
  }
}
