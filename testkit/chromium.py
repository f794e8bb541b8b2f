"""The flags every headless Chromium gets, in the browser tests (test/browser/conftest.py) and in the page benches
(bench/page_bench.py, bench/badlink_clients.py): Debian's chromium, no sandbox or GPU in a container, and none of
its own network traffic (updates, sync, QUIC) beside what is measured or tested."""

CHROMIUM_FLAGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-dev-shm-usage",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
