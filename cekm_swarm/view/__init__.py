"""``cekm view``: a live 2-D view of a running or replayed run in the browser.

:mod:`.live` holds what the view shows (pure, fed with key and payload, tested without
Zenoh); :mod:`.server` serves it over HTTP (the page and a Server-Sent Events stream);
:mod:`.command` is the click command.
"""
