"""Data files shipped with lsys3d (installed as the package ``lsys3d.assets``)."""
