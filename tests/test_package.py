import pkgutil
import subprocess
import sys

import primlib


def test_every_subpackage_loads_by_attribute_access():
    # issue 12: `import primlib as pl; pl.contour` raised AttributeError. A fresh interpreter,
    # so no earlier import has already bound the subpackages as attributes.
    names = sorted(
        m.name for m in pkgutil.iter_modules(primlib.__path__) if not m.name.startswith("_")
    )
    assert {"contour", "nurbs", "plot", "io", "match"} <= set(names)
    code = (
        "import sys, primlib as pl\n"
        f"for name in {names!r}:\n"
        "    assert getattr(pl, name).__name__ == 'primlib.' + name, name\n"
        "    assert name in dir(pl), name\n"
        "try:\n"
        "    pl.no_such_thing\n"
        "except AttributeError:\n"
        "    pass\n"
        "else:\n"
        "    sys.exit('pl.no_such_thing did not raise AttributeError')\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
