"""A Sphinx extension that writes the API reference pages from the code: one page per room of kincal (its
``__all__``, documented by autodoc and numpydoc) and the top-level face, each name linked to the room that
documents it. Written at every build, so the reference cannot drift from the code."""
from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

import kincal

HEAD = {"kincal": "The public face: ``import kincal``"}
LEAVES = ("kincal.errors", "kincal.units", "kincal.ties")  # modules every room uses: the errors, units, ties


def rooms() -> list[str]:
    """The rooms of kincal: its sub-packages with an ``__all__`` (the command line has its own page)."""
    out = []
    for info in pkgutil.iter_modules(kincal.__path__):
        if info.ispkg and info.name != "cli":
            out.append(f"kincal.{info.name}")
    return sorted(out) + list(LEAVES)


def _room_page(room: str) -> str:
    title = f"``{room}``"
    return f"{title}\n{'=' * len(title)}\n\n.. automodule:: {room}\n   :members:\n"


def _face_page(names: list[str], where: dict[str, str]) -> str:
    title = HEAD["kincal"]
    lines = [title, "=" * len(title), "", ".. automodule:: kincal", "   :no-members:", "",
             "Each name is documented in its room:", ""]
    lines += [f"- :py:obj:`kincal.{n} <{where[n]}.{n}>`" for n in names]
    return "\n".join(lines) + "\n"


def _index_page(names: list[str]) -> str:
    lines = ["API reference", "=============", "", ".. toctree::", "   :maxdepth: 1", ""]
    lines += [f"   {n}" for n in names]
    return "\n".join(lines) + "\n"


def write_pages(app) -> None:
    """Write ``reference/api/*.rst`` (only when their text changes, so an unchanged build stays incremental)."""
    out = Path(app.srcdir) / "reference" / "api"
    out.mkdir(parents=True, exist_ok=True)
    names = rooms()
    where = {}
    for room in names:
        mod = importlib.import_module(room)
        for n in getattr(mod, "__all__", [n for n in vars(mod) if not n.startswith("_")]):
            where.setdefault(n, room)
    pages = {room: _room_page(room) for room in names}
    pages["kincal"] = _face_page(list(kincal.__all__), where)
    pages["index"] = _index_page(["kincal", *names])
    for name, text in pages.items():
        path = out / f"{name}.rst"
        if not path.exists() or path.read_text() != text:
            path.write_text(text)


def setup(app):
    app.connect("builder-inited", write_pages)
    return {"parallel_read_safe": True, "version": "1"}
