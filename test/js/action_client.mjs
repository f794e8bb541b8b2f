// roslibjs's actionlib client (ROSLIB.ActionClient and Goal, as the console's Actions tab uses them) in Node,
// driven by test/integration/test_actions_roslibjs.py: sends a goal of order 8 to an actionlib/TestAction server
// and waits for its result, then sends one of order 200 and cancels it after its first feedback; prints one JSON
// line: {"done": {feedback, result, status}, "cancelled": {feedback, result, status}}.
// Usage: ROSLIB=roslib1|roslib2 node action_client.mjs ws://127.0.0.1:PORT /server
const library = await import(process.env.ROSLIB || 'roslib1');
const ROSLIB = library.default || library; // 1.x is CommonJS (one default object), 2.x an ES module

const [url, serverName] = process.argv.slice(2);
const ros = new ROSLIB.Ros({url});
ros.on('error', (error) => { console.log(JSON.stringify({error: String(error?.message || error)})); process.exit(1); });
const client = new ROSLIB.ActionClient({ros, serverName, actionName: 'actionlib/TestAction'});

function run(order, cancelAfterFirst) {
  return new Promise((resolve) => {
    const goal = new ROSLIB.Goal({actionClient: client, goalMessage: {goal: order}});
    const seen = {feedback: [], result: null, status: null};
    goal.on('feedback', (feedback) => {
      seen.feedback.push(feedback.feedback);
      if (cancelAfterFirst && seen.feedback.length === 1) goal.cancel();
    });
    goal.on('status', (status) => { seen.status = status.status; });
    goal.on('result', (result) => { seen.result = result.result; setTimeout(() => resolve(seen), 100); });
    goal.send();
  });
}

setTimeout(async () => {  // (the bridge's goal publisher has reached the server by then)
  const done = await run(8, false);
  const cancelled = await run(200, true);
  console.log(JSON.stringify({done, cancelled}));
  client.dispose();
  ros.close();
  process.exit(0);
}, 1500);
