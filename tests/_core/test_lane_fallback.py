"""The lane interpreter is an optimization that can only fail soft: where it cannot or should not
run (a primitive this JAX lacks, an untested JAX, a platform other than the CPU, JAXSAMPLE_LANES=0)
`lane_map` is `jax.vmap`, `computed_once` packs nothing, and every estimate, gradient and sample is
the same to float rounding; a missing primitive is one warning, never an ImportError; the JAX
internals the package reads are imported in one module (`jaxsample._core.jax_internals`)."""

import ast
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxsample as js
from jaxsample import scene
from jaxsample._core import computed_once as computed_once_module
from jaxsample._core import cpu_paths, jax_internals, lanes
from jaxsample._core.lanes import LaneFallback, LanesUnavailableWarning, lane_map
from keyring import next_key

PACKAGE = Path(js.__file__).resolve().parent
A = jnp.array([0.3, -0.2, 0.9327379], jnp.float32)
N = 4096

# jax.extend is JAX's public API for extensions; these are the package's uses of it outside the
# internal module (the engine replays a per-point jaxpr).
PUBLIC_EXTEND_USES = {"estimators/engine.py": {"ClosedJaxpr", "jaxpr_as_fun"}}


def _internal_uses(path: Path) -> list[str]:
    """Imports of jax._src, jax.interpreters or jax.extend (but the public uses listed above), and the
    attributes jax._src, jax.interpreters, jax.extend and jax.core.* other than Tracer, in one file."""
    relative = path.relative_to(PACKAGE).as_posix()
    allowed = PUBLIC_EXTEND_USES.get(relative, set())
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found += [f"import {a.name}" for a in node.names
                      if a.name.startswith(("jax._src", "jax.interpreters", "jax.extend"))]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            module = node.module
            names = {a.name for a in node.names}
            if module == "jax" and names & {"_src", "interpreters", "extend", "core"}:
                found.append(f"from jax import {sorted(names)}")
            elif module.startswith(("jax._src", "jax.interpreters")):
                found.append(f"from {module} import {sorted(names)}")
            elif module.startswith("jax.extend") and not names <= allowed:
                found.append(f"from {module} import {sorted(names - allowed)}")
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "jax":
            if node.attr in ("_src", "interpreters", "extend"):
                found.append(f"jax.{node.attr}")
        elif (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Attribute)
              and isinstance(node.value.value, ast.Name) and node.value.value.id == "jax"
              and node.value.attr == "core" and node.attr != "Tracer"):
            found.append(f"jax.core.{node.attr}")
    return [f"{relative}:{use}" for use in found]


def test_nothing_outside_the_internal_module_reaches_into_jax_internals():
    """Catches a new `jax._src` / `jax.interpreters` import (or a `jax.core` internal) anywhere in
    the package but `_core/jax_internals.py`: outside it, an import that a JAX release moves is an
    ImportError of the whole package, which that module exists to prevent. Checks the checker too."""
    uses = [use for path in sorted(PACKAGE.rglob("*.py")) if path.name != "jax_internals.py"
            for use in _internal_uses(path)]
    assert uses == []
    own = _internal_uses(PACKAGE / "_core" / "jax_internals.py")
    assert any("jax._src.lax" in use for use in own) and any("jax.interpreters" in use for use in own), own


A_RELU3 = lambda x: jnp.maximum(x @ A, 0.0) ** 3  # noqa: E731  (`x @ a`: a dot on the lanes, a dot_general in vmap)
LIGHTS = [scene.SphereLight(jnp.array([-0.9, 0.0, 3.0]), 0.3, 10.0), scene.ConstantSky(0.2)]


def _phong(exponent, key):
    return js.estimate(lambda x: x[2] ** 3, js.PhongLobe(exponent), key, N).mean


def _shade(exponent, key):
    return scene.shade(jnp.zeros(3), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.3, 0.0, 0.954]),
                       scene.Phong(exponent, 0.9), LIGHTS, key, N, strategy="mis").mean


def _quadratic(c, key):
    """An estimate of 9 moving coordinates (past FORWARD_WIDTH: the loop differentiated in reverse)."""
    return js.estimate(lambda x: jnp.sum(c * jnp.concatenate([x, x * x, x[:1] * x[1:], x[1:2] * x[2:]])),
                       js.UniformSphere(), key, N).mean


# Each takes a key. The engine's main paths: a value, the derivative of an estimate (the forward
# stream: `_differentiable_stream`, `_pushforward`), `scene.shade`.
ENGINE = {
    "value": lambda key: js.estimate(A_RELU3, js.CosineHemisphere(), key, N).mean,
    "grad": lambda key: jax.grad(_phong)(5.0, key),
    "shade": lambda key: _shade(50.0, key),
}
# The rest: a JVP, a vmap of estimates over keys, the reverse-mode loop, samples with their density,
# the derivative of `shade` (a derivative program of its own: the silhouette's boundary term).
MORE = {
    "jvp": lambda key: jax.jvp(lambda e: _phong(e, key), (5.0,), (1.0,))[1],
    "vmap": lambda key: jax.vmap(lambda k: js.estimate(A_RELU3, js.CosineHemisphere(), k, N).mean)(
        jax.random.split(key, 3)),
    "reverse": lambda key: jax.grad(_quadratic)(jnp.linspace(0.5, 1.3, 9), key),
    "sample": lambda key: js.PhongLobe(7.0).sample_with_pdf(key, (1000,)),
    "shade_grad": lambda key: jax.grad(_shade)(50.0, key),
}


@pytest.fixture
def switch(monkeypatch):
    """switch(mode): JAXSAMPLE_LANES as if the process had started with it ('auto', 'off', 'on').
    The compiled programs are dropped at each switch and after the test, so that no program cached
    by a jitted entry (estimate, shade, sample) is reused across settings or leaks to other tests."""
    def set_mode(mode):
        jax.clear_caches()
        monkeypatch.setattr(cpu_paths, "SETTING", mode)

    yield set_mode
    jax.clear_caches()


def _on_and_off(programs, switch):
    """Each program's result with the lanes ('auto' on the CPU) and switched off, on the same keys
    (all programs in one compiled program per setting)."""
    keys = [next_key() for _ in programs]
    run = jax.jit(lambda keys: {name: fn(k) for (name, fn), k in zip(programs.items(), keys)})
    results = []
    for mode in ("auto", "off"):
        switch(mode)
        results.append(run([jax.random.clone(k) for k in keys]))
    return results


def _assert_close(got, expected):
    for name in expected:
        jax.tree.map(lambda g, e: np.testing.assert_allclose(g, e, rtol=2e-5, atol=1e-6, err_msg=name),
                     got[name], expected[name])


def _program(key):
    return str(jax.make_jaxpr(lambda k: js.estimate(A_RELU3, js.CosineHemisphere(), k, N).mean)(key))


def test_switched_off_the_engine_runs_vmap_and_gives_the_same_estimates(switch):
    """Catches the switch not reaching the engine's program (off, it keeps the lanes: no
    `dot_general`, a `cond` of `computed_once`) and a vmap path that breaks a value, the forward
    derivative stream or `scene.shade`: each agrees with the lanes to float rounding."""
    on, off = _on_and_off(ENGINE, switch)
    _assert_close(off, on)
    key = next_key()
    switch("auto")
    program_on = _program(jax.random.clone(key))
    switch("off")
    program_off = _program(key)
    assert "dot_general" not in program_on and " cond[" in program_on
    assert "dot_general" in program_off and " cond[" not in program_off


def test_switched_off_jvps_vmaps_reverse_loops_samples_and_shade_derivatives_are_the_same(switch):
    """Catches a vmap path that breaks a JVP of an estimate, a vmap of estimates, the loop
    differentiated in reverse (9 moving coordinates), `sample_with_pdf`, or the derivative of
    `scene.shade`: each agrees with the lanes to float rounding."""
    on, off = _on_and_off(MORE, switch)
    _assert_close(off, on)


def test_on_another_platform_lane_map_is_vmap_and_computed_once_the_identity(monkeypatch, switch):
    """Catches the CPU devices running on a GPU or TPU (they were measured only on XLA's CPU
    backend): with the traced program's platform another one, `lane_map` binds vmap's
    `dot_general` and `computed_once` no `cond`, silently; JAXSAMPLE_LANES=1 brings both back."""
    switch("auto")
    monkeypatch.setattr(cpu_paths, "trace_platform", lambda: "gpu")
    pts = jax.random.normal(next_key(), (64, 3))
    lanes_in = tuple(pts[:, j] for j in range(3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        program = str(jax.make_jaxpr(lambda c: lane_map(lambda x: x @ A, 64)(c))(lanes_in))
        once = str(jax.make_jaxpr(lambda v, t: computed_once_module.computed_once(v, t))(
            [pts[:, 0], pts[:, 1]], jnp.uint32(3)))
    assert "dot_general" in program and " cond[" not in once
    np.testing.assert_allclose(lane_map(lambda x: x @ A, 64)(lanes_in), pts @ A, rtol=1e-6)
    switch("on")
    assert "dot_general" not in str(jax.make_jaxpr(lambda c: lane_map(lambda x: x @ A, 64)(c))(lanes_in))


def test_a_missing_primitive_is_one_warning_and_vmap(monkeypatch, switch):
    """Catches a missing primitive raising (the import-time ImportError that made one renamed
    primitive break the whole package, or an error when a program is traced) and a warning per
    program instead of one per process: two programs, one `LanesUnavailableWarning` naming the
    primitive, and both evaluated by vmap with vmap's values. `strict=True` says why it cannot run."""
    switch("auto")
    monkeypatch.setattr(lanes, "_MISSING", ["zeta"])
    monkeypatch.setattr(lanes, "_warned", False)
    pts = jax.random.normal(next_key(), (64, 3))
    lanes_in = tuple(pts[:, j] for j in range(3))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        first = str(jax.make_jaxpr(lambda c: lane_map(lambda x: x @ A, 64)(c))(lanes_in))
        second = lane_map(lambda x: jnp.sum(x * A), 64)(pts)
    ours = [w for w in caught if issubclass(w.category, LanesUnavailableWarning)]
    assert len(ours) == 1 and "zeta" in str(ours[0].message), [str(w.message) for w in caught]
    assert "dot_general" in first
    np.testing.assert_allclose(second, jax.vmap(lambda x: jnp.sum(x * A))(pts), rtol=1e-6)
    with pytest.raises(LaneFallback, match="zeta"):
        lane_map(lambda x: x @ A, 64, strict=True)(lanes_in)


def test_an_untested_jax_steps_aside_with_a_warning_unless_asked(monkeypatch, switch):
    """Catches the interpreter running on a JAX version it was not tested with (its jaxpr walk and
    bind parameters are JAX internals), and JAXSAMPLE_LANES=1 not overriding that check."""
    switch("auto")
    monkeypatch.setattr(jax_internals, "jax_version", lambda: (99, 0, 0))
    monkeypatch.setattr(lanes, "_warned", False)
    pts = jax.random.normal(next_key(), (64, 3))
    trace = lambda: str(jax.make_jaxpr(lane_map(lambda x: x @ A, 64))(pts))  # noqa: E731
    with pytest.warns(LanesUnavailableWarning, match="not a version it was tested with"):
        assert "dot_general" in trace()
    switch("on")
    assert "dot_general" not in trace()


SCRIPT = """
import json, sys, warnings
import jax, jax.lax
import jax.numpy as jnp
from jax.extend.core import primitives
# A JAX that renamed a primitive of the lane tables: zeta_p is gone from the modules they read.
for module in (jax.lax, primitives):
    if hasattr(module, "zeta_p"):
        delattr(module, "zeta_p")
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    import jaxsample as js
    from jaxsample._core import lanes
    key_value, key_grad = (jax.random.wrap_key_data(jnp.asarray(k, jnp.uint32)) for k in json.loads(sys.argv[1]))
    A = jnp.array([0.3, -0.2, 0.9327379], jnp.float32)
    relu3 = lambda x: jnp.maximum(x @ A, 0.0) ** 3
    phong = lambda e, key: js.estimate(lambda x: x[2] ** 3, js.PhongLobe(e), key, 4096).mean
    value = js.estimate(relu3, js.CosineHemisphere(), key_value, 4096).mean
    grad = jax.grad(phong)(5.0, key_grad)
    program = str(jax.make_jaxpr(lambda k: js.estimate(relu3, js.CosineHemisphere(), k, 4096).mean)(key_value))
warned = [str(w.message) for w in caught if issubclass(w.category, lanes.LanesUnavailableWarning)]
print(json.dumps({"value": float(value), "grad": float(grad), "missing": lanes._MISSING, "warned": warned,
                  "vmap": "dot_general" in program}))
"""


def test_a_jax_without_a_primitive_imports_warns_once_and_estimates_in_subprocess():
    """Catches the ImportError of a JAX that renamed one primitive of the tables (the package was
    unimportable): with `zeta_p` removed before `import jaxsample`, the import works, one warning
    names it, the estimates run by vmap, and a value and a gradient agree with the lanes' here."""
    keys = [next_key() for _ in range(2)]
    data = json.dumps([np.asarray(jax.random.key_data(k)).tolist() for k in keys])
    expected_value = js.estimate(lambda x: jnp.maximum(x @ A, 0.0) ** 3, js.CosineHemisphere(), keys[0], N).mean
    expected_grad = jax.grad(lambda e: js.estimate(lambda x: x[2] ** 3, js.PhongLobe(e), keys[1], N).mean)(5.0)
    env = {k: v for k, v in os.environ.items() if k != cpu_paths.ENV}
    out = subprocess.run([sys.executable, "-c", SCRIPT, data], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["missing"] == ["zeta"] and got["vmap"], got
    assert len(got["warned"]) == 1 and "zeta" in got["warned"][0], got["warned"]
    np.testing.assert_allclose(got["value"], expected_value, rtol=2e-5)
    np.testing.assert_allclose(got["grad"], expected_grad, rtol=2e-5, atol=1e-7)


def test_the_switch_values():
    """Catches a misread value of JAXSAMPLE_LANES: the documented spellings of off and on, and any
    other value read as auto with a warning (never an error: the switch must not break an import)."""
    assert [cpu_paths.parse(v) for v in ("0", "off", " False", "no")] == ["off"] * 4
    assert [cpu_paths.parse(v) for v in ("1", "ON", "true", "yes")] == ["on"] * 4
    assert [cpu_paths.parse(v) for v in ("", "auto", "AUTO")] == ["auto"] * 3
    with pytest.warns(RuntimeWarning, match="JAXSAMPLE_LANES='fast'"):
        assert cpu_paths.parse("fast") == "auto"


OFF_SCRIPT = """
import json, sys
import jax, jax.numpy as jnp
import jaxsample as js
from jaxsample._core import cpu_paths
A = jnp.array([0.3, -0.2, 0.9327379], jnp.float32)
key = jax.random.wrap_key_data(jnp.asarray(json.loads(sys.argv[1]), jnp.uint32))
program = str(jax.make_jaxpr(lambda k: js.estimate(lambda x: jnp.maximum(x @ A, 0.0) ** 3, js.CosineHemisphere(),
                                                   k, 4096).mean)(key))
print(cpu_paths.setting(), "dot_general" in program, " cond[" in program)
"""


def test_jaxsample_lanes_0_in_the_environment_turns_the_lanes_off_in_subprocess():
    """Catches JAXSAMPLE_LANES ignored: a process started with JAXSAMPLE_LANES=0 traces an estimate
    as vmap does (a `dot_general`, no `cond` of `computed_once`)."""
    env = dict(os.environ, **{cpu_paths.ENV: "0"})
    data = json.dumps(np.asarray(jax.random.key_data(next_key())).tolist())
    out = subprocess.run([sys.executable, "-c", OFF_SCRIPT, data], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.split() == ["off", "True", "False"], (out.stdout, out.stderr[-3000:])
