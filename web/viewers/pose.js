// One turtle's turtlesim/Pose in turtlesim's world, with the trail it leaves while shown (parts/world-view.js draws it as the
// page's live world does, in the turtle's colour there).
import { WorldView } from '../parts/world-view.js';

export class TurtlePoseViewer {
  constructor(element, { topic }) {
    element.innerHTML = '<div class="stage"><canvas role="img" aria-label="The turtle in its world"></canvas></div>';
    this.view = new WorldView(element.querySelector('canvas'));
    this.name = topic.split('/').at(-2) || topic;  // /turtle2/pose: turtle2
  }

  draw(pose) {
    this.view.setPose(this.name, pose);
  }

  close() {
    this.view.close();
  }
}
