"""Using an adapter without its library names the extra that installs it, in the library's words."""

import sys

import pytest

import jaxsample as js
from jaxsample import adapters

CONVERTERS = [("numpyro", "jaxsample.adapters._numpyro", adapters.to_numpyro, "NumPyro"),
              ("distrax", "jaxsample.adapters._distrax", adapters.to_distrax, "distrax"),
              ("tensorflow_probability", "jaxsample.adapters._tfp", adapters.to_tfp, "TensorFlow Probability")]


@pytest.mark.parametrize("library,module,convert,name", CONVERTERS, ids=[c[0] for c in CONVERTERS])
def test_a_missing_library_names_the_extra(monkeypatch, library, module, convert, name):
    monkeypatch.setitem(sys.modules, library, None)  # what `import library` sees when it is not installed
    monkeypatch.delitem(sys.modules, module, raising=False)
    with pytest.raises(ImportError, match=rf'needs {name}.*pip install "jaxsample\[adapters\]"') as raised:
        convert(js.CosineHemisphere())
    assert raised.value.name == library


def test_sphere_reparam_names_the_extra_too(monkeypatch):
    monkeypatch.setitem(sys.modules, "numpyro", None)
    monkeypatch.delitem(sys.modules, "jaxsample.adapters._numpyro", raising=False)
    with pytest.raises(ImportError, match=r'jaxsample\[adapters\]'):
        adapters.SphereReparam  # noqa: B018
