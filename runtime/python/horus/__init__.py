"""HORUS: the Python runtime (seed 001's API) over the C++ core.

`horus` shares its name with the generated message packages (`horus.msg`, installed in another
folder of sys.path), so the package path is extended to every `horus/` folder on sys.path.
"""
from pkgutil import extend_path

__path__ = extend_path(__path__, __name__)
