"""The public face is documented the scientific-Python way: every name in every room's ``__all__`` has a numpydoc
docstring whose Parameters match its signature (no parameter missing, none stale) and whose Returns (or Yields)
says what a function gives back; the Examples sections run as doctests. Parsed by numpydoc's own reader, so what is
checked here is what the documentation site renders."""
import doctest
import importlib
import inspect
import pkgutil

import pytest
from numpydoc.docscrape import ClassDoc, FunctionDoc

import kincal

ROOMS = ["kincal"] + sorted(f"kincal.{m.name}" for m in pkgutil.iter_modules(kincal.__path__)
                            if m.ispkg and m.name != "cli")
MIN_EXAMPLES = 40


def _public(room: str) -> list[tuple[str, object]]:
    mod = importlib.import_module(room)
    out = []
    for name in mod.__all__:
        obj = getattr(mod, name)
        if inspect.isclass(obj) or inspect.isfunction(obj):
            out.append((name, obj))
    return out


def _signature_names(obj) -> list[str] | None:
    """The parameters a reader passes (self, cls left out); None when the signature is not the class's own (an
    exception's or a protocol's inherited constructor)."""
    if inspect.isclass(obj):
        init = obj.__dict__.get("__init__") or next((c.__dict__["__init__"] for c in obj.__mro__[1:]
                                                     if "__init__" in c.__dict__), None)
        if init in (object.__init__, BaseException.__init__) or issubclass(obj, BaseException):
            return None
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return None
    names = []
    for p in sig.parameters.values():
        if p.name in ("self", "cls"):
            continue
        names.append({p.VAR_POSITIONAL: f"*{p.name}", p.VAR_KEYWORD: f"**{p.name}"}.get(p.kind, p.name))
    return names


def _documented(section) -> list[str]:
    return [n.strip() for item in section for n in item.name.split(",") if n.strip()]


def _returns_something(obj) -> bool:
    ann = inspect.signature(obj).return_annotation
    return ann not in (None, "None")


def _problems(name: str, obj) -> list[str]:
    doc = ClassDoc(obj, config={"show_class_members": False}) if inspect.isclass(obj) else FunctionDoc(obj)
    out = []
    if not doc["Summary"]:
        out.append("no one-line summary")
    wanted = _signature_names(obj)
    if wanted is not None:
        given = _documented(doc["Parameters"]) + _documented(doc["Other Parameters"])
        strip = [g.lstrip("*") for g in given]
        missing = [w for w in wanted if w.lstrip("*") not in strip]
        stale = [g for g in given if g.lstrip("*") not in [w.lstrip("*") for w in wanted]]
        if missing:
            out.append(f"Parameters misses {missing}")
        if stale:
            out.append(f"Parameters names {stale}, not in the signature")
    if inspect.isfunction(obj) and _returns_something(obj) and not (doc["Returns"] or doc["Yields"]):
        out.append("no Returns section")
    return [f"{name}: {p}" for p in out]


@pytest.mark.parametrize("room", ROOMS)
def test_every_public_name_has_a_numpydoc_docstring(room):
    problems = [p for name, obj in _public(room) for p in _problems(f"{room}.{name}", obj)]
    assert not problems, "\n".join(problems)


def _modules():
    out = []
    for info in pkgutil.walk_packages(kincal.__path__, "kincal."):
        if ".cli" in info.name:
            continue
        out.append(importlib.import_module(info.name))
    return [kincal, *out]


def test_the_examples_run():
    """Every Examples section in the package runs as a doctest (ELLIPSIS and whitespace-normalised), and there are
    at least ``MIN_EXAMPLES`` of them."""
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    seen, examples = set(), 0
    for mod in _modules():
        for test in finder.find(mod, mod.__name__):
            if not test.examples or test.name in seen:
                continue
            seen.add(test.name)
            examples += 1
            runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0
    assert examples >= MIN_EXAMPLES, f"{examples} docstrings with examples; {MIN_EXAMPLES} wanted"
