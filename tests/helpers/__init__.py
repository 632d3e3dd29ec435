"""The tests' shared helpers, one home (importable as ``helpers``: pytest puts ``tests/`` on
the path, ``pythonpath`` in pyproject.toml): processes whose output lines are waited on
with a timeout (:mod:`.processes`), ``cekm launch`` as a process (:mod:`.launch`), a
Foxglove WebSocket client (:mod:`.foxglove`) and the namespace hosts' addresses
(:mod:`.netns_hosts`)."""
