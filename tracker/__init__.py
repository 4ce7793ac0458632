"""Video to tracked 3-D poses: silhouettes, filtering, outputs and the ``track`` command."""
