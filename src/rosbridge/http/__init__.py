"""The HTTP endpoints beside the websocket: the page's files, camera streams, clouds, bags, access rules."""
