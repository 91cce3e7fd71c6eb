"""The type stubs (`ferrobot/_native.pyi`) and the extension agree: every class, method,
property and function the module has is in the stubs, and nothing the stubs promise is
missing; every public callable has a docstring (what `help()` shows)."""

import ast
import inspect
import pathlib

import ferrobot
from ferrobot import _native

STUBS = pathlib.Path(ferrobot.__file__).with_name("_native.pyi")
DUNDER_OK = {"__init__", "__len__", "__getitem__", "__iter__"}


def _stub_names():
    tree = ast.parse(STUBS.read_text())
    classes, functions = {}, set()
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            classes[node.name] = {
                n.name for n in node.body if isinstance(n, ast.FunctionDef)
            }
        elif isinstance(node, ast.FunctionDef):
            functions.add(node.name)
    return classes, functions


def _public(cls):
    return {n for n in dir(cls) if not n.startswith("_")}


def test_stubs_match_the_module():
    classes, functions = _stub_names()
    module_classes = {n for n, v in vars(_native).items() if inspect.isclass(v)}
    module_functions = {
        n for n, v in vars(_native).items() if callable(v) and not inspect.isclass(v) and not n.startswith("_")
    }
    assert module_classes == set(classes), module_classes ^ set(classes)
    assert module_functions == functions, module_functions ^ functions
    for name, methods in classes.items():
        runtime = _public(getattr(_native, name))
        stubbed = {m for m in methods if not m.startswith("_")}
        assert runtime == stubbed, (name, runtime ^ stubbed)
        for m in methods & DUNDER_OK - {"__init__", "__iter__"}:
            assert hasattr(getattr(_native, name), m), (name, m)


def test_everything_public_has_a_docstring():
    for n, v in vars(_native).items():
        if n.startswith("_") or not callable(v):
            continue
        assert (v.__doc__ or "").strip(), n
        if inspect.isclass(v):
            for m in _public(v):
                doc = getattr(v, m).__doc__
                assert (doc or "").strip(), f"{n}.{m}"


def test_the_package_exports_what_it_says():
    for name in ferrobot.__all__:
        assert hasattr(ferrobot, name), name
