// Every panel and every viewer of the page, in one table: app.js makes the page from it and from nothing else.
//
// A panel (parts/panel.js says its shape): `name` keys its element ids and the ?tab= of the address, `title`
// names it (its tab in the console, its card's heading, or its region), `place` is where it lives: 'bar' (the
// page's header, before the connection's badge), 'world' (the world's card, in order), 'side' (a card beside the
// world) or 'console' (a tab).
//
// A viewer draws the messages of one topic, offered for the message `types` it declares wherever that topic is
// opened (the Topics panel). Its shape, the whole of it:
//   new Viewer(element, { topic, type, onChange, onDrawn })  fills element (empty, its own) for that topic;
//                                         onChange() is for the viewer to call when what it asks of the
//                                         subscription changes; onDrawn({ stamp, bytes, noun, via }) for one that
//                                         draws what it fetches itself (a cloud by /cloud, a picture by its
//                                         stream): each thing drawn, whose rate and age the topic then shows;
//   viewer.draw(message)                  each message, as the subscription delivers it;
//   viewer.close()                        it is taken away: stop its timers;
//   static subscription (optional)        what it asks of the topic's subscription while shown (e.g. binary CBOR);
//   viewer.subscription (optional)        the same, when it depends on the session: read at each subscribe;
//                                         null when the viewer needs no messages from it;
//   viewer.attach(session), viewer.detach()  (optional) the connected RosSession, and its loss, for a viewer that
//                                         fetches more than its messages (the image viewer's picture stream).
import { WorldPanel } from './panels/world.js';
import { DrivePanel } from './panels/drive.js';
import { TwistPanel } from './panels/twist.js';
import { WorldToolsPanel } from './panels/world-tools.js';
import { TopicsPanel } from './panels/topics.js';
import { PublishPanel } from './panels/publish.js';
import { ServicesPanel } from './panels/services.js';
import { ParamsPanel } from './panels/params.js';
import { NodesPanel } from './panels/nodes.js';
import { CameraPanel } from './panels/camera.js';
import { LogsPanel } from './panels/logs.js';
import { LinkPanel } from './panels/link.js';
import { BagsPanel } from './panels/bags.js';
import { ReconfigurePanel } from './panels/reconfigure.js';
import { ActionsPanel } from './panels/actions.js';
import { ImageViewer } from './viewers/image.js';
import { TurtlePoseViewer } from './viewers/pose.js';
import { LaserScanViewer } from './viewers/laser.js';
import { TrailViewer } from './viewers/trail.js';
import { OccupancyGridViewer } from './viewers/map.js';
import { TfViewer } from './viewers/tf.js';
import { NavSatFixViewer } from './viewers/navsat.js';
import { DiagnosticsViewer } from './viewers/diagnostics.js';
import { GaugesViewer } from './viewers/gauges.js';
import { PointCloudViewer } from './viewers/cloud.js';

// In the order shown; the console's tabs in the order of the tutorial's terminal windows.
export const PANELS = [
  { name: 'link', title: 'Link health', place: 'bar', Panel: LinkPanel },
  { name: 'world', title: 'Turtle world', place: 'world', Panel: WorldPanel },
  { name: 'camera', title: 'Camera', place: 'world', Panel: CameraPanel },
  { name: 'drive', title: 'Drive', place: 'world', Panel: DrivePanel },
  { name: 'twist', title: 'Publish a Twist', place: 'side', Panel: TwistPanel },
  { name: 'world-tools', title: 'World', place: 'side', Panel: WorldToolsPanel },
  { name: 'topics', title: 'Topics', place: 'console', Panel: TopicsPanel },
  { name: 'publish', title: 'Publish', place: 'console', Panel: PublishPanel },
  { name: 'services', title: 'Services', place: 'console', Panel: ServicesPanel },
  { name: 'params', title: 'Parameters', place: 'console', Panel: ParamsPanel },
  { name: 'nodes', title: 'Nodes', place: 'console', Panel: NodesPanel },
  { name: 'logs', title: 'Logs', place: 'console', Panel: LogsPanel },
  { name: 'bags', title: 'Bags', place: 'console', Panel: BagsPanel },
  { name: 'reconfigure', title: 'Reconfigure', place: 'console', Panel: ReconfigurePanel },
  { name: 'actions', title: 'Actions', place: 'console', Panel: ActionsPanel },
];

export const VIEWERS = [
  { name: 'turtle', title: 'World', types: ['turtlesim/Pose'], Viewer: TurtlePoseViewer },
  { name: 'image', title: 'Picture', types: ['sensor_msgs/Image', 'sensor_msgs/CompressedImage'], Viewer: ImageViewer },
  { name: 'laser', title: 'Laser', types: ['sensor_msgs/LaserScan'], Viewer: LaserScanViewer },
  { name: 'trail', title: 'Trail', types: ['nav_msgs/Odometry', 'geometry_msgs/PoseStamped', 'nav_msgs/Path'],
    Viewer: TrailViewer },
  { name: 'map', title: 'Map', types: ['nav_msgs/OccupancyGrid'], Viewer: OccupancyGridViewer },
  { name: 'tf', title: 'TF tree', types: ['tf2_msgs/TFMessage'], Viewer: TfViewer },
  { name: 'navsat', title: 'GPS track', types: ['sensor_msgs/NavSatFix'], Viewer: NavSatFixViewer },
  { name: 'diagnostics', title: 'Status table', types: ['diagnostic_msgs/DiagnosticArray'], Viewer: DiagnosticsViewer },
  { name: 'gauges', title: 'Gauges', types: ['sensor_msgs/JointState', 'sensor_msgs/Imu', 'sensor_msgs/BatteryState',
    'sensor_msgs/Range'], Viewer: GaugesViewer },
  { name: 'cloud', title: 'Cloud', types: ['sensor_msgs/PointCloud2'], Viewer: PointCloudViewer },
];

export function viewersFor(type) {
  return VIEWERS.filter(viewer => viewer.types.includes(type));
}
