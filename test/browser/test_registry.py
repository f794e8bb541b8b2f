"""The page is made from web/registry.js and nothing else, and none of its modules does anything when imported:
only app.js's start() does."""


def registry(page, expression):
    """The value of expression (JavaScript, over the module's exports PANELS and VIEWERS), imported in the page."""
    return page.driver.execute_async_script(f"""const done = arguments[arguments.length - 1];
        import('/registry.js').then(({{ PANELS, VIEWERS }}) => done({expression}), error => done(String(error)));""")


def test_the_tabs_and_cards_come_from_the_registry(open_page):
    page = open_page()
    rows = registry(page, "PANELS.map(({ name, title, place }) => [name, title, place])")
    tabs = page.js("return [...document.querySelectorAll('.console [role=tab]')].map(b => [b.id, b.textContent])")
    assert tabs == [[f"tab-button-{name}", title] for name, title, place in rows if place == "console"]
    panels = page.js("return [...document.querySelectorAll('.console [role=tabpanel]')].map(e => e.id)")
    assert panels == [f"tab-{name}" for name, title, place in rows if place == "console"]
    cards = page.js("return [...document.querySelectorAll('.side > .card h2')].map(h => h.firstChild.textContent)")
    assert cards == [title for name, title, place in rows if place == "side"]
    world = page.js("return [...document.querySelectorAll('.world > section')].map(s => s.getAttribute('aria-label'))")
    assert world == [title for name, title, place in rows if place == "world"]


def test_importing_the_pages_modules_does_nothing(open_page, bridge_url):
    page = open_page()
    page.driver.get(bridge_url + "world-constants.js")  # a document of the page's origin that runs none of them
    body = page.js("return document.body.innerHTML")
    imported = page.driver.execute_async_script("""const done = arguments[arguments.length - 1];
        const sockets = [];
        window.WebSocket = class { constructor(url) { sockets.push(url); } };
        const timers = [];
        for (const name of ['setTimeout', 'setInterval', 'requestAnimationFrame']) {
          const original = window[name];
          window[name] = (...args) => {
            if (new Error().stack.includes(location.origin)) timers.push(name);  // (the page's, not the driver's)
            return original(...args);
          };
        }
        import('/app.js').then(app => done({ exports: Object.keys(app), sockets, timers }), e => done(String(e)));""")
    assert imported == {"exports": ["start"], "sockets": [], "timers": []}
    assert page.js("return document.body.innerHTML") == body
    assert page.js("return window.turtleView") is None
