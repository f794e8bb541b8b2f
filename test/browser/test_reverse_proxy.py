"""The console behind a reverse proxy at a sub-path, as a robot is put on the internet: Debian's nginx in front of
the demo's bridge at /rover1/, over http and over https (a self-signed certificate), with README's own nginx
snippet, the page opened by a public name (robots.example, which Chromium resolves to 127.0.0.1) that the bridge's
allowed_origins allows, as README says. In headless Chromium the page connects, drives the turtle, shows the camera
by the proxied JPEG stream and downloads a bag, every address it uses under /rover1/."""

import http.client
import re
import ssl
import subprocess
import textwrap
from urllib.parse import urlsplit

import pytest
from selenium.webdriver.support.ui import Select
from std_srvs.srv import Empty

from turtlesim.msg import Pose

from fixtures import From, bridge_fixture
from harness import ARTIFACTS, REPO, Proc, free_port, wait_for
from sensor_messages import CAMERA

CENTRE = 5.544444561004639
PUBLIC = "robots.example"
NGINX_CONFIG = """daemon off;
master_process off;  # one process, run as whoever starts it (no workers switching to another user)
pid {tmp}/nginx.pid;
error_log {tmp}/error.log;
events {{ worker_connections 256; }}
http {{
    access_log {tmp}/access.log;
    client_body_temp_path {tmp}/client_body;
    proxy_temp_path {tmp}/proxy;
    fastcgi_temp_path {tmp}/fastcgi;
    uwsgi_temp_path {tmp}/uwsgi;
    scgi_temp_path {tmp}/scgi;
    server {{
        listen 127.0.0.1:{http_port};
{location}
    }}
    server {{
        listen 127.0.0.1:{https_port} ssl;
        ssl_certificate {tmp}/cert.pem;
        ssl_certificate_key {tmp}/key.pem;
{location}
    }}
}}
"""


def readme_location(bridge_port):
    """README's nginx `location /rover1/ { ... }` block, pointed at the test's bridge."""
    found = re.search(
        r"^( +)location /rover1/ \{\n.*?^\1\}$", (REPO / "README.md").read_text(), re.MULTILINE | re.DOTALL
    )
    assert found, "README.md has no nginx `location /rover1/ { ... }` block"
    assert "proxy_pass http://127.0.0.1:9090/;" in found[0]
    return textwrap.indent(textwrap.dedent(found[0]).replace("127.0.0.1:9090", f"127.0.0.1:{bridge_port}"), " " * 8)


@pytest.fixture(scope="module")
def bag_folder(tmp_path_factory):
    return tmp_path_factory.mktemp("bags")


# this module's bridge records bags (the shared one of conftest.py does not), and allows the public name's pages
# (README: behind a reverse proxy)
bridge_url = bridge_fixture(
    "rosbridge_proxied",
    yields="url",
    needs=("sim",),
    bag_folder=From("bag_folder"),
    allowed_origins=f"[http://{PUBLIC}:*, https://{PUBLIC}:*]",
)


@pytest.fixture(scope="module")
def nginx(bridge_url, tmp_path_factory):
    """Debian's nginx, unprivileged, everything of its own in a tmp dir, README's location block in a server of each
    scheme: {"http": port, "https": port}."""
    tmp = tmp_path_factory.mktemp("nginx")
    subprocess.run(
        [
            "openssl",
            "req",
            "-x509",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:prime256v1",
            "-nodes",
            "-days",
            "1",
            "-subj",
            f"/CN={PUBLIC}",
            "-addext",
            f"subjectAltName=DNS:{PUBLIC}",
            "-keyout",
            str(tmp / "key.pem"),
            "-out",
            str(tmp / "cert.pem"),
        ],
        check=True,
        capture_output=True,
    )
    ports = {"http": free_port(), "https": free_port()}
    config = tmp / "nginx.conf"
    config.write_text(
        NGINX_CONFIG.format(
            tmp=tmp,
            http_port=ports["http"],
            https_port=ports["https"],
            location=readme_location(urlsplit(bridge_url).port),
        )
    )
    # (-e: the error log before the config is read, which would otherwise be /var/log/nginx's)
    proc = Proc(
        ["/usr/sbin/nginx", "-e", str(tmp / "error.log"), "-p", str(tmp), "-c", str(config)], None, tmp / "nginx.out"
    )
    try:
        wait_for(lambda: proc.alive() and (tmp / "nginx.pid").exists() or not proc.alive(), 10, what="nginx")
        assert proc.alive(), f"nginx ended:\n{proc.output()}\n{(tmp / 'error.log').read_text(errors='replace')}"
        yield ports
    finally:
        proc.stop()


def get(url):
    """(status, headers, body) of a GET of a URL of the public name, sent to 127.0.0.1 with the name as its Host
    (a redirect is not followed), the test's certificate accepted."""
    parts = urlsplit(url)
    connection = (
        http.client.HTTPSConnection("127.0.0.1", parts.port, timeout=10, context=ssl._create_unverified_context())
        if parts.scheme == "https"
        else http.client.HTTPConnection("127.0.0.1", parts.port, timeout=10)
    )
    try:
        connection.request(
            "GET", f"{parts.path}?{parts.query}" if parts.query else parts.path, headers={"Host": parts.netloc}
        )
        answer = connection.getresponse()
        return answer.status, answer.headers, answer.read()
    finally:
        connection.close()


def text_of(page, selector):
    return page.js("return document.querySelector(arguments[0])?.textContent ?? ''", selector)


def shot(page, name, scroll):
    """A screenshot of the page with `scroll` scrolled to the top of the screen."""
    page.js("document.querySelector(arguments[0]).scrollIntoView()", scroll)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.driver.save_screenshot(str(ARTIFACTS / f"{name}.png"))


def bag_names(page):
    """{name: (its link, whether it is being recorded)} of the Bags tab's list."""
    return {
        name: (href, recording)
        for name, href, recording in page.js(
            """return [...document.querySelectorAll('#tab-bags tr[data-bag]')].map(r => [r.dataset.bag,
            r.querySelector('a').href, r.querySelector('.bag-size').textContent.includes('recording')])"""
        )
    }


# The page at /rover1/ and at /rover1/index.html, each with a query the address keeps.
@pytest.mark.parametrize("scheme, address", [("http", "?drive=%2Fturtle1%2Fcmd_vel"), ("https", "index.html?tab=bags")])
def test_the_console_at_a_sub_path_of_nginx_connects_drives_shows_the_camera_and_downloads_a_bag(
    nginx, camera, node, listen, open_page, scheme, address, tmp_path
):
    base = f"{scheme}://{PUBLIC}:{nginx[scheme]}/rover1/"
    socket_url = base.replace(scheme, "wss" if scheme == "https" else "ws", 1)
    status, headers, _ = get(base[:-1])
    assert (status, headers["Location"]) == (301, base)  # nginx sends /rover1 to /rover1/ (README)
    node.wait_for_service("/reset", 30)
    node.ServiceProxy("/reset", Empty)()
    poses = listen("/turtle1/pose", Pose)
    wait_for(
        lambda: poses.last and poses.last.linear_velocity == 0 and abs(poses.last.x - CENTRE) < 1e-4,
        15,
        what="turtle1 at rest in the centre",
    )

    page = open_page(
        url=base + address,
        flags=[
            f"--host-resolver-rules=MAP {PUBLIC} 127.0.0.1",
            *(["--ignore-certificate-errors"] if scheme == "https" else []),
        ],
    )
    page.driver.execute_cdp_cmd("Browser.setDownloadBehavior", {"behavior": "allow", "downloadPath": str(tmp_path)})
    # Drives: one Twist published from the page moves turtle1 about 2 m, seen by ROS and by the page.
    page.fill("linear", "2.0")
    page.fill("angular", "0")
    page.el("publish").click()
    wait_for(lambda: poses.last.x > CENTRE + 1, 15, what="turtle1 driven by the page")
    wait_for(lambda: (page.pose("turtle1") or {}).get("x", 0) > CENTRE + 1, 10, what="the page's pose moved")

    # The camera, by the bridge's JPEG stream through the proxy.
    wait_for(
        lambda: page.js(
            "return [...document.getElementById('camera-topic').options].some(o => o.value === arguments[0])", CAMERA
        ),
        20,
        what=f"{CAMERA} listed",
    )
    Select(page.el("camera-topic")).select_by_value(CAMERA)
    wait_for(
        lambda: (
            "JPEG stream" in text_of(page, ".camera-panel .camera-stats")
            and not text_of(page, ".camera-panel .camera-stats").startswith("0")
        ),
        15,
        what="frames arriving",
    )
    shot(page, f"reverse-proxy-{scheme}-driver", "body")

    # A bag recorded from the Bags tab, and downloaded by its link.
    if "tab=bags" not in address:
        page.tab("bags")
    page.click('#tab-bags input[type=checkbox][value="/turtle1/pose"]')
    listed = bag_names(page)  # (the module's other test may have left one)
    page.click("#tab-bags .bag-start")
    wait_for(lambda: "Recording" in text_of(page, "#tab-bags .bag-recording"), 10, what="the recording shown")
    wait_for(lambda: " 0 messages" not in text_of(page, "#tab-bags .bag-recording"), 10, what="messages counted")
    page.click("#tab-bags .bag-stop")
    name, link = wait_for(
        lambda: next(
            ((n, href) for n, (href, recording) in bag_names(page).items() if n not in listed and not recording), None
        ),
        10,
        what="the bag listed",
    )
    assert link == f"{base}bags/{name}"
    shot(page, f"reverse-proxy-{scheme}-bags", "#tab-bags")
    page.click(f'#tab-bags a[href="{link}"]')
    downloaded = tmp_path / name
    # (Chromium reserves the name with an empty file at the start and writes a .crdownload beside it until done)
    wait_for(
        lambda: downloaded.exists() and downloaded.stat().st_size and not list(tmp_path.glob("*.crdownload")),
        10,
        what=f"{name} downloaded by Chromium",
    )
    assert downloaded.read_bytes()[:13] == b"#ROSBAG V2.0\n"
    assert get(link)[::2] == (200, downloaded.read_bytes())

    # Every address the page used was under /rover1/ of nginx's port, the websocket's included.
    used = {url for url in page.network_urls() if not url.startswith(("data:", "blob:"))}
    assert socket_url in used
    assert any(url.startswith(f"{base}stream?topic=%2Fturtle_camera%2Fimage_raw") for url in used)
    assert [url for url in used if not url.startswith((base, socket_url))] == []
    assert page.console_errors() == []
