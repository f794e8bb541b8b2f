// turtlesim's world as src/turtlesim/sim.py makes it, for the page's drawing and forms; what follows
// `export default` is plain JSON, which test/unit/test_page_constants.py reads and checks against sim.py (the bridge
// serves the page's .js files, not .json ones).
export default {
  "size_m": 11.088889122009277,
  "size_px": 500,
  "first_turtle": {"x": 5.544444561004639, "y": 5.544444561004639, "theta": 0.0},
  "background": [69, 86, 255],
  "pen": [179, 184, 255],
  "pen_width_px": 3
};
