"""The public API: the modules a plugin may import are exactly ``impala_flow.PUBLIC_MODULES``,
each declares its names in ``__all__``, every one of them exists, and the callables among them
are documented (the API page of the docs is generated from them)."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import pytest

import impala_flow


def _engine_modules() -> list[str]:
    names = ["impala_flow"]
    for info in pkgutil.walk_packages(impala_flow.__path__, "impala_flow."):
        names.append(info.name)
    return names


def _is_public(module: str) -> bool:
    return not any(part.startswith("_") for part in module.split(".")[1:])


def test_public_modules_are_the_declared_ones() -> None:
    found = {m for m in _engine_modules() if _is_public(m)}
    assert found == set(impala_flow.PUBLIC_MODULES), (
        "a module without a leading _ is public: list it in impala_flow.PUBLIC_MODULES or rename it _name; "
        f"undeclared {sorted(found - set(impala_flow.PUBLIC_MODULES))}, "
        f"missing {sorted(set(impala_flow.PUBLIC_MODULES) - found)}")


@pytest.mark.parametrize("module", impala_flow.PUBLIC_MODULES)
def test_public_module_declares_documented_names(module: str) -> None:
    mod = importlib.import_module(module)
    assert mod.__doc__ and mod.__doc__.strip(), f"{module} has no docstring"
    names = getattr(mod, "__all__", None)
    assert names, f"{module} has no __all__: its public names are undeclared"
    assert len(set(names)) == len(names), f"{module}.__all__ lists a name twice"
    for name in names:
        assert hasattr(mod, name), f"{module}.__all__ lists {name}, which it does not define"
        value = getattr(mod, name)
        if inspect.isclass(value) or inspect.isfunction(value):
            assert inspect.getdoc(value), f"{module}.{name} has no docstring"
