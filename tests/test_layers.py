"""The import contract: every import of the package (those inside functions included) runs
down the layers of docs/architecture.md, torch stays off the light paths, and no module
imports itself through others.

    common → objects → sensor_sim → rig (transport → drivers → sim; core) → protocols
    → acquisition → dataset → model → cli

(protocols sit beside the rig: they import neither it nor anything above.) Inside model, its
sub-packages are layers too (``MODEL_ROOMS``): each imports only those before it.
"""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("common", "objects", "sensor_sim", "rig", "protocols", "acquisition", "dataset", "model", "cli")

# What each layer may import from the project (besides itself). Rig's inner layers are
# listed by module prefix; the longest matching prefix decides.
RIG_BASE = ("rig", "rig.errors", "rig.clock", "rig.types", "rig.config")
ALLOWED: dict[str, tuple[str, ...]] = {
    "common": (),
    "objects": ("common",),
    "sensor_sim": ("common", "objects"),
    "rig.errors": ("common",),
    "rig.clock": (),
    "rig.types": ("common", "rig.errors"),
    "rig.config": ("common", "rig.errors"),
    "rig.transport": ("common", *RIG_BASE),
    "rig.drivers": ("common", *RIG_BASE, "rig.transport"),
    # device simulators speak the drivers' bytes: they may share framing helpers and
    # register tables with them, and compute with the physics library
    "rig.sim": ("common", "objects", "sensor_sim", *RIG_BASE, "rig.transport", "rig.drivers"),
    "rig": ("common", "objects", *RIG_BASE, "rig.transport", "rig.drivers"),  # rig.py, motion, factory, safety
    "protocols": ("common", "objects"),
    "acquisition": ("common", "objects", "protocols", "rig"),
    "dataset": ("common", "objects", "protocols", "acquisition"),
    "model": ("common", "objects", "sensor_sim", "protocols", "acquisition", "dataset"),
    "cli": PACKAGES,
}
# model's sub-packages, bottom to top: each may import what model may, and the sub-packages before it.
MODEL_ROOMS = (
    "model.denoiser",  # config, network, diffusion, samplers, checkpoints
    "model.conditioning",  # the physics channels and their caches
    "model.generation",  # a trained model loaded and sampled
    "model.sweeps",  # the force sweep
    "model.evaluation",  # evaluate: metrics, baselines, report, figures
    "model.training",  # the trainer, its callbacks, train
    "model.compare",  # compare: settings over seeds
)
ALLOWED.update({room: (*ALLOWED["model"], *MODEL_ROOMS[:i]) for i, room in enumerate(MODEL_ROOMS)})
FORBIDDEN_BELOW = {  # finer rules inside an allowed package
    "acquisition": ("rig.sim",),  # a hardware run never needs the simulator
    "rig": ("rig.sim",),  # the rig opens what the config names; the simulated rig is handed in
}
NO_TORCH = ("common", "objects", "sensor_sim", "rig", "protocols", "acquisition", "dataset")
TORCH_ALLOWED = ("dataset.torch_dataset",)  # the PyTorch Dataset: imported by training only
HEAVY = ("torch", "diffusers", "accelerate", "safetensors")
# A module over LONG lines says why it is one module, near its top: "# Over 400 lines (N): <why>",
# N within a tenth of its real length (a reason is looked at again as the file grows).
LONG = 400
REASON = re.compile(r"# Over 400 lines \((\d+)\)")


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@cache
def modules() -> dict[str, Path]:
    return {module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


@cache
def imports(name: str) -> tuple[tuple[str, int], ...]:
    """(imported module, line) for every import in the module, at any depth."""
    path = modules()[name]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.module, node.lineno))
            # `from pkg import module` imports a module too
            found += [
                (f"{node.module}.{a.name}", node.lineno) for a in node.names if f"{node.module}.{a.name}" in modules()
            ]
    return tuple(found)


def layer_of(name: str, table) -> str:
    best = ""
    for key in table:
        if (name == key or name.startswith(key + ".")) and len(key) > len(best):
            best = key
    return best


def project(name: str) -> bool:
    return name.split(".")[0] in PACKAGES


def within(name: str, prefixes) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def test_every_package_module_is_known():
    assert len(modules()) > 50
    for name in modules():
        assert layer_of(name, ALLOWED), f"{name} belongs to no layer"


@pytest.mark.parametrize("name", sorted(m for m in modules()))
def test_imports_run_down_the_layers(name):
    layer = layer_of(name, ALLOWED)
    allowed = (layer, *ALLOWED[layer])
    bad = []
    for target, line in imports(name):
        if not project(target):
            continue
        if within(target, FORBIDDEN_BELOW.get(layer, ())) and not within(name, FORBIDDEN_BELOW.get(layer, ())):
            bad.append(f"line {line}: {target}")
        elif not within(target, allowed) and layer_of(target, ALLOWED) not in allowed:
            bad.append(f"line {line}: {target} (layer {layer_of(target, ALLOWED)})")
    assert not bad, f"{name} (layer {layer}) imports against the layers: {bad}"


@pytest.mark.parametrize("name", sorted(m for m in modules() if within(m, NO_TORCH) and m not in TORCH_ALLOWED))
def test_no_torch_on_the_light_paths(name):
    heavy = [f"line {line}: {t}" for t, line in imports(name) if t.split(".")[0] in HEAVY]
    assert not heavy, f"{name} imports {heavy}"


def test_no_import_cycle():
    graph = {name: {t for t, _ in imports(name) if t in modules() and t != name} for name in modules()}
    # a package's __init__ importing its own submodules is not a cycle of layers
    for name in graph:
        graph[name] = {t for t in graph[name] if not t.startswith(name + ".")}
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


def test_the_contract_catches_a_wrong_arrow(tmp_path, monkeypatch):
    """The checker itself: a protocol module importing the rig is reported."""
    fake = tmp_path / "protocols" / "bad.py"
    fake.parent.mkdir()
    fake.write_text("def f():\n    from rig.rig import Rig\n")
    monkeypatch.setitem(modules(), "protocols.bad", fake)
    imports.cache_clear()
    with pytest.raises(AssertionError, match="protocols.bad .* rig.rig"):
        test_imports_run_down_the_layers("protocols.bad")
    imports.cache_clear()


def test_the_contract_catches_a_model_room_importing_one_above_it(tmp_path, monkeypatch):
    """The checker itself: the denoiser importing the trainer is reported; every sub-package of
    model is one of MODEL_ROOMS."""
    fake = tmp_path / "model" / "denoiser" / "bad.py"
    fake.parent.mkdir(parents=True)
    fake.write_text("from model.training.trainer import Trainer\n")
    monkeypatch.setitem(modules(), "model.denoiser.bad", fake)
    imports.cache_clear()
    with pytest.raises(AssertionError, match="model.denoiser.bad .* model.training.trainer"):
        test_imports_run_down_the_layers("model.denoiser.bad")
    imports.cache_clear()
    rooms = {p.parent.relative_to(ROOT).as_posix().replace("/", ".") for p in (ROOT / "model").glob("*/__init__.py")}
    assert rooms == set(MODEL_ROOMS)


def test_a_long_module_says_why_it_is_one():
    """Every module over 400 lines has "# Over 400 lines (N): <why>" in its first 30 lines,
    with N within 10 % of its line count."""
    bad = []
    for path in sorted(modules().values()):
        lines = path.read_text().splitlines()
        if len(lines) <= LONG:
            continue
        where = f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path} ({len(lines)} lines)"
        found = [m for m in (REASON.match(line) for line in lines[:30]) if m]
        if not found:
            bad.append(f"{where}: no '# Over 400 lines (N): <why>' in its first 30 lines; split it or say why not")
        elif abs(int(found[0].group(1)) - len(lines)) > 0.1 * len(lines):
            bad.append(f"{where}: its reason says {found[0].group(1)}: is the reason still true? update N")
    assert not bad, "long modules:\n" + "\n".join(bad)


def test_the_long_module_check_reads_n(tmp_path, monkeypatch):
    """The checker itself: a long module without a reason, or with a stale N, is reported."""
    body = "x = 1\n" * 450
    for name, head in (("silent", ""), ("stale", "# Over 400 lines (300): one reason\n")):
        fake = tmp_path / "common" / f"{name}.py"
        fake.parent.mkdir(exist_ok=True)
        fake.write_text('"""doc"""\n' + head + body)
        monkeypatch.setitem(modules(), f"common.{name}", fake)
    stale = r"stale\.py \(452 lines\): its reason says 300"
    with pytest.raises(AssertionError, match=r"silent\.py \(451 lines\): no .*\n.*" + stale):
        test_a_long_module_says_why_it_is_one()
