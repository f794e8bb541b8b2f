// A roslibjs 1.x client in Node, driven by test_bridge_with_roslibjs.py: it runs the steps named on the command
// line against the bridge and prints one JSON line per result ({"step": ..., ...}) on stdout.
// Usage: node roslibjs_client.js ws://127.0.0.1:PORT step...
'use strict';
const ROSLIB = require('roslib');

const [url, ...steps] = process.argv.slice(2);
const report = (step, fields) => console.log(JSON.stringify({step, ...fields}));
const fail = (step, error) => { report(step, {error: String(error)}); process.exit(1); };

const ros = new ROSLIB.Ros({url});
ros.on('error', (error) => fail('connect', error && error.message || error));

function call(name, request) {
  return new Promise((resolve, reject) => {
    new ROSLIB.Service({ros, name}).callService(new ROSLIB.ServiceRequest(request), resolve, reject);
  });
}

const STEPS = {
  // the turtle's pose, as a subscriber gets it
  pose: () => new Promise((resolve) => {
    const topic = new ROSLIB.Topic({ros, name: '/turtle1/pose', messageType: 'turtlesim/Pose'});
    topic.subscribe((pose) => { topic.unsubscribe(); resolve({pose}); });
  }),
  // drive forward for a second: Topic.publish advertises first, as roslibjs always does
  drive: () => new Promise((resolve) => {
    const cmd = new ROSLIB.Topic({ros, name: '/turtle1/cmd_vel', messageType: 'geometry_msgs/Twist'});
    const twist = new ROSLIB.Message({linear: {x: 2, y: 0, z: 0}, angular: {x: 0, y: 0, z: 0}});
    const timer = setInterval(() => cmd.publish(twist), 100);
    setTimeout(() => { clearInterval(timer); resolve({published: true}); }, 1500);
  }),
  topics: () => new Promise((resolve, reject) => ros.getTopics((result) => resolve(result), reject)),
  spawn: async () => ({spawned: await call('/spawn', {x: 2, y: 2, theta: 0, name: 'js_turtle'})}),
  missing: () => call('/no_such_service', {}).then(
    (values) => ({values}), (error) => ({error: String(error)})),
  params: () => new Promise((resolve) => {
    const param = new ROSLIB.Param({ros, name: '/js_test/answer'});
    param.set({answer: 42, list: [1, 'two']}, () => param.get((value) => resolve({value})));
  }),
  // provide a service and wait for one ROS call of it (made by the test with rosservice)
  serve: () => new Promise((resolve) => {
    const service = new ROSLIB.Service({ros, name: '/js_test/flip', serviceType: 'std_srvs/SetBool'});
    service.advertise((request, response) => {
      response.success = !request.data;
      response.message = 'flipped by roslibjs';
      setTimeout(() => resolve({request}), 200);
      return true;
    });
    setTimeout(() => report('serve-ready', {}), 500);
  }),
};

ros.on('connection', async () => {
  for (const step of steps) {
    try {
      report(step, await STEPS[step]());
    } catch (error) {
      fail(step, error);
    }
  }
  ros.close();
  process.exit(0);
});
