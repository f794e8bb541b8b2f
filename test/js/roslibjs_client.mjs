// A roslibjs client in Node, driven by test_bridge_with_roslibjs.py: it runs the steps named on the command line
// against the bridge and prints one JSON line per result ({"step": ..., ...}) on stdout.
// Usage: ROSLIB=roslib1|roslib2 node roslibjs_client.mjs ws://127.0.0.1:PORT step...
// ROSLIB names one of the versions of test/js/package.json (npm aliases of roslib 1.x and 2.x). Messages and
// requests are plain objects, which both take (2.x has no ROSLIB.Message or ServiceRequest).
const library = await import(process.env.ROSLIB || 'roslib1');
const ROSLIB = library.default || library; // 1.x is CommonJS (one default object), 2.x an ES module

const [url, ...steps] = process.argv.slice(2);
const report = (step, fields) => console.log(JSON.stringify({step, ...fields}));
const fail = (step, error) => { report(step, {error: String(error)}); process.exit(1); };

const ros = new ROSLIB.Ros({url});
ros.on('error', (error) => fail('connect', error && error.message || error));

function call(name, request) {
  return new Promise((resolve, reject) => new ROSLIB.Service({ros, name}).callService(request, resolve, reject));
}

// provide a service and wait for one ROS call of it (made by the test with rosservice)
const serve = (name) => () => new Promise((resolve) => {
  const service = new ROSLIB.Service({ros, name, serviceType: 'std_srvs/SetBool'});
  service.advertise((request, response) => {
    response.success = !request.data;
    response.message = 'flipped by roslibjs';
    setTimeout(() => resolve({request}), 200);
    return true;
  });
  setTimeout(() => report('serve-ready', {}), 500);
});

const STEPS = {
  // the turtle's pose, as a subscriber gets it
  pose: () => new Promise((resolve) => {
    const topic = new ROSLIB.Topic({ros, name: '/turtle1/pose', messageType: 'turtlesim/Pose'});
    topic.subscribe((pose) => { topic.unsubscribe(); resolve({pose}); });
  }),
  // drive forward for a second: Topic.publish advertises first, as roslibjs always does
  drive: () => new Promise((resolve) => {
    const cmd = new ROSLIB.Topic({ros, name: '/turtle1/cmd_vel', messageType: 'geometry_msgs/Twist'});
    const twist = {linear: {x: 2, y: 0, z: 0}, angular: {x: 0, y: 0, z: 0}};
    const timer = setInterval(() => cmd.publish(twist), 100);
    setTimeout(() => { clearInterval(timer); resolve({published: true}); }, 1500);
  }),
  topics: () => new Promise((resolve, reject) => ros.getTopics((result) => resolve(result), reject)),
  spawn: async () => ({spawned: await call('/spawn', {x: 2, y: 2, theta: 0, name: 'js_turtle'})}),
  clear: async () => ({cleared: await call('clear', {})}), // a relative name, resolved in the bridge's namespace
  missing: () => call('/no_such_service', {}).then(
    (values) => ({values}), (error) => ({error: String(error)})),
  params: () => new Promise((resolve, reject) => {
    const param = new ROSLIB.Param({ros, name: '/js_test/answer'});
    param.set({answer: 42, list: [1, 'two']}, () => param.get((value) => resolve({value}), reject), reject);
  }),
  // roslibjs's examples/simple.html in order: publish a Twist on /cmd_vel, hear /listener once, call
  // /add_two_ints (std_srvs/SetBool here: rospy_tutorials is not packaged by Debian), list the params, set and
  // read max_vel_y and favorite_color (relative names)
  'simple-example': async () => {
    new ROSLIB.Topic({ros, name: '/cmd_vel', messageType: 'geometry_msgs/Twist'})
      .publish({linear: {x: 0.1, y: 0.2, z: 0.3}, angular: {x: -0.1, y: -0.2, z: -0.3}});
    const heard = await new Promise((resolve) => {
      const listener = new ROSLIB.Topic({ros, name: '/listener', messageType: 'std_msgs/String'});
      listener.subscribe((message) => { listener.unsubscribe(); resolve(message.data); });
    });
    const sum = await call('/add_two_ints', {data: true});
    const params = await new Promise((resolve, reject) => ros.getParams(resolve, reject));
    const setThenGet = (name, value) => new Promise((resolve, reject) => {
      const param = new ROSLIB.Param({ros, name});
      param.set(value, () => param.get(resolve, reject), reject);
    });
    return {heard, sum, params, max_vel_y: await setThenGet('max_vel_y', 0.8),
            favorite_color: await setThenGet('favorite_color', 'red')};
  },
  serve: serve('/js_test/flip'),
  'serve-relative': serve('js_test/relative_flip'),
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
