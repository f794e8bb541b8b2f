// The bad-link benchmark's eye in the page (bench/badlink.py injects it with Selenium): at every animation frame
// it reads the camera picture the page shows, from its pixels, and the small topic's value, from its text, and
// records how old each new one is when first on screen. Only what a person sees counts: the stamp comes from the
// barcode bench/rover.py draws into the picture's top rows (32 blocks: black, white, 24 bits of the publish time
// in ms modulo 2^24, a 6-bit check), not from any message the page received.
//
// The camera is whatever <img> or <canvas> shows a readable barcode (tried in turn until one does, and again when
// it stops: the console's panels may change how they show it). window.badlink holds, all with wall times in ms:
//   camera: [[shown at, age]]  small: [[shown at, age]]  frames: [animation frame times]
//   readouts: [[at, text]]  (the page's own camera readout, once a second, to compare with the pixels)
//   inView: [[at, camera on screen, small topic on screen]]  (once a second: at least half of each in the viewport)
//   element: a description of the element read
// The first time it finds the camera it scrolls it into view, as a person watching it would.
(function () {
  const config = window.badlinkConfig || {};
  const CELLS = 32, BITS = 24, CHECK = 6, MODULO = 1 << BITS, BAND = 48 / 480;
  const probe = document.createElement('canvas');
  probe.width = CELLS * 4;
  probe.height = 4;
  const g = probe.getContext('2d', { willReadFrequently: true });
  const state = window.badlink = { camera: [], small: [], frames: [], readouts: [], inView: [], element: null,
    misses: 0 };
  let source = null, smallElement = null, lastStamp = null, lastSmall = null, lastReadout = 0;

  function checkBits(data) {
    const groups = [18, 12, 6, 0].map(shift => (data >> shift) & 63);
    return (groups[0] + 3 * groups[1] + 5 * groups[2] + 7 * groups[3] + 11) & 63;
  }

  function size(el) {
    return el instanceof HTMLImageElement ? [el.naturalWidth, el.naturalHeight] : [el.width, el.height];
  }

  // The 24-bit stamp an element shows, or null.
  function read(el) {
    const [w, h] = size(el);
    if (w < 32 || h < 24) return null;
    let px;
    try {
      g.clearRect(0, 0, probe.width, probe.height);
      g.drawImage(el, 0, 0, w, h * BAND, 0, 0, probe.width, probe.height);
      px = g.getImageData(0, 2, probe.width, 1).data;
    } catch (error) {
      return null;  // (not decoded yet, or from another origin)
    }
    const level = i => (px[16 * i + 8] + px[16 * i + 9] + px[16 * i + 10]) / 3;  // block i's middle
    const black = level(0), white = level(1);
    if (white - black < 80) return null;
    const bits = [];
    for (let i = 2; i < CELLS; i++) bits.push(level(i) > (black + white) / 2 ? 1 : 0);
    let data = 0, check = 0;
    for (let i = 0; i < BITS; i++) data = data * 2 + bits[i];
    for (let i = BITS; i < BITS + CHECK; i++) check = check * 2 + bits[i];
    return check === checkBits(data) ? data : null;
  }

  function onScreen(el) {
    if (!el || !el.isConnected) return false;
    const r = el.getBoundingClientRect();
    const w = Math.min(r.right, innerWidth) - Math.max(r.left, 0), h = Math.min(r.bottom, innerHeight) - Math.max(r.top, 0);
    return r.width > 0 && r.height > 0 && w > 0 && h > 0 && w * h >= 0.5 * r.width * r.height;
  }

  function visible(el) {
    const r = el.getBoundingClientRect();
    return el.isConnected && r.width >= 32 && r.height >= 24;
  }

  function find() {
    for (const el of document.querySelectorAll('img, canvas')) {
      if (el !== probe && visible(el) && read(el) !== null) return el;
    }
    return null;
  }

  function describe(el) {
    const src = el.getAttribute('src') || '';
    return `${el.tagName.toLowerCase()}${el.className ? '.' + String(el.className).split(' ').join('.') : ''}` +
      `${src ? ` src=${src.slice(0, 120)}` : ''} ${size(el).join('x')}`;
  }

  function tick() {
    const now = Date.now();
    state.frames.push(now);
    let stamp = source && visible(source) ? read(source) : null;
    if (stamp === null) {
      state.misses++;
      if (!source || state.misses % 15 === 0) {  // look again (every ~0.25 s while nothing readable is shown)
        const found = find();
        if (found) {
          if (!source) found.scrollIntoView({ block: 'nearest' });
          source = found;
          state.element = describe(found);
          stamp = read(found);
        }
      }
    }
    if (stamp !== null && stamp !== lastStamp) {
      lastStamp = stamp;
      let age = ((now % MODULO) - stamp + MODULO) % MODULO;
      if (age > MODULO / 2) age -= MODULO;
      state.camera.push([now, age]);
    }
    for (const selector of config.smallSelectors || []) {
      const el = document.querySelector(selector);
      const match = el && /(\d{9,}\.\d+)/.exec(el.textContent);
      if (match) {
        smallElement = el;
        if (match[1] !== lastSmall) {
          lastSmall = match[1];
          state.small.push([now, now - Number(match[1]) * 1000]);
        }
        break;
      }
    }
    if (now - lastReadout >= 1000) {
      lastReadout = now;
      const readout = document.querySelector(config.readoutSelector || '.camera-stats');
      if (readout) state.readouts.push([now, readout.textContent]);
      state.inView.push([now, onScreen(source), onScreen(smallElement)]);
    }
    requestAnimationFrame(tick);
  }
  requestAnimationFrame(tick);
})();
