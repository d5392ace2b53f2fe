"""The ``mimic`` command line, and nothing else: ``mimic.cli:main`` (``python -m mimic``),
one module per subcommand, the argument groups they share in ``mimic.args``. The library
is in ``control`` (motion, graph, clusters, transitions, the avatar, choice and sketch),
``silhouette_bank`` (rendering, features, the bank) and ``vision`` (the online loop)."""
