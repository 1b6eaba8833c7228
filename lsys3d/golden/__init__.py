"""Golden files: a recipe and its report per tree, ``lsys3d check``, and the pytest plugin (``testing``)."""
