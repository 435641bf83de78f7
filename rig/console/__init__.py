"""The operator's console: a live web page for the running test (``docs/console.md``).

- :mod:`~rig.console.app` — the ASGI application (Starlette): the page, its WebSocket feed, the controls
- :mod:`~rig.console.state` — what a browser that connects needs (status, run header, the last 20 s)
- :mod:`~rig.console.hub` — the connected browsers, one bounded queue each (frames dropped and counted)
- :mod:`~rig.console.feed` — the rig service's zenoh telemetry, the console's only data path
- :mod:`~rig.console.token` — the operator token, HMAC-SHA256(rig key, "operator-console")
- :mod:`~rig.console.browsers` — the browser sessions the token opens (HttpOnly cookie, CSRF token)
- :mod:`~rig.console.access` — the tokens file of operators and viewers, re-read when it changes
- :mod:`~rig.console.https` — the HTTPS certificate, given or made on first use
- :mod:`~rig.console.guard` — the HTTP connections bounded (request timeout, per-client and total caps)
- :mod:`~rig.console.server` — serving it with uvicorn (``rig console``) and as a child process
"""

from rig.console.app import Console, create_app
from rig.console.server import ConsoleError, ConsoleProcess, WebAccess, serve_console
from rig.console.token import operator_token, token_from_key_file

__all__ = [
           "Console",
           "ConsoleError",
           "ConsoleProcess",
           "WebAccess",
           "create_app",
           "operator_token",
           "serve_console",
           "token_from_key_file",
]
