"""``python -m cdpm.viewer``: the meshcat server process started by the viewer."""

from cdpm.viewer.server import _serve

if __name__ == "__main__":  # not when a tool merely imports the package's modules
    _serve()
