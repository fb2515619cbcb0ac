"""The live dashboard: watch a run, act on it, replay it (``wncs dashboard``, ``wncs run
--dashboard``).

The dashboard is an observer, not a clock participant. It reads the run's history
(``history.sqlite``, which the historian commits every round) incrementally, so a live run and a
finished one are read by the same code, in the historian's deterministic order, and attaching
late loses nothing. It acts only through the path ``wncs inject`` takes (``ops/inject`` to the
clock), so every button press is stamped into the history and a replay reproduces it.

- :mod:`dashboard.feed` reads new history rows and validates each body against its key's schema;
- :mod:`dashboard.view` turns rows into time-stamped records for the page (decimated);
- :mod:`dashboard.commands` checks a request from the page and turns it into an inject request;
- :mod:`dashboard.server` is the ASGI app (Starlette): the page, its static files, the WebSocket.
"""
