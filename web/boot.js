// Loaded before the rest: when one of the page's libraries cannot be loaded (web/vendor/ missing, e.g. a clone
// where tools/setup was not run), the page says which and how to get them, instead of "Connecting…" forever.
// (The bridge warns of the same when it starts: pages.py finds the vendor/ files the page's files name.)
// It is the one script that acts as it loads, not from app.js's start(): a file that fails to load is seen only by
// a listener already in place, and app.js itself may be the module that cannot load.
{
  const LIBRARIES = ['vendor/roslib.min.js', 'vendor/uPlot.esm.js', 'vendor/uPlot.min.css'];
  let reported = false;

  const report = async () => {
    reported = true;
    const found = await Promise.all(LIBRARIES.map(file => fetch(file, { method: 'HEAD', cache: 'no-store' })
      .then(answer => answer.ok, () => false)));
    const missing = LIBRARIES.filter((file, i) => !found[i]).map(file => file.split('/').pop());
    if (!missing.length) return;
    if (document.readyState === 'loading') await new Promise(resolve => addEventListener('DOMContentLoaded', resolve));
    const banner = document.getElementById('page-error');
    banner.textContent = `${missing.join(', ')} could not be loaded: the page's libraries are missing from its ` +
      'vendor/ folder. Run bash tools/setup in the turtlesim source folder (it installs them from npm), then reload.';
    banner.hidden = false;
    document.getElementById('conn').dataset.state = 'error';
    document.getElementById('conn-text').textContent = 'Page incomplete';
  };

  // A script or style sheet that fails to load fires 'error' on its element, which reaches window when captured;
  // for a module, the failure of any file it imports fires on its <script type="module">.
  addEventListener('error', event => {
    if (!reported && (event.target instanceof HTMLScriptElement || event.target instanceof HTMLLinkElement)) report();
  }, true);
}
