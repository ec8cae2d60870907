"""Check every internal link of the built site: each ``href`` or ``src`` to a page, file or ``#anchor`` of the
site must exist. Usage: ``python docs/check_links.py docs/_build/html`` (exit 1 with the broken links listed)."""
from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.links: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag, attrs) -> None:
        for key, value in attrs:
            if key in ("href", "src") and value:
                self.links.append(value)
            if key in ("id", "name") and value:
                self.ids.add(value)


def _parsed(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8", errors="replace"))
    return page


def broken(root: Path) -> list[str]:
    """The internal links of the HTML pages under ``root`` that lead nowhere, as "page: link"."""
    pages = {p: _parsed(p) for p in sorted(root.rglob("*.html"))}
    out = []
    for path, page in pages.items():
        for link in page.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith(("mailto:", "javascript:", "data:")):
                continue  # the site's own links only
            target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
            if target.is_dir():
                target = target / "index.html"
            if not target.exists():
                out.append(f"{path.relative_to(root)}: {link} (no such file)")
            elif parts.fragment and target.suffix == ".html":
                ids = pages[target].ids if target in pages else _parsed(target).ids
                if unquote(parts.fragment) not in ids:
                    out.append(f"{path.relative_to(root)}: {link} (no such anchor)")
    return out


def main() -> int:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/_build/html").resolve()
    if not (root / "index.html").exists():
        print(f"{root}: no built site (run make docs)", file=sys.stderr)
        return 1
    bad = broken(root)
    for line in bad:
        print(line)
    pages = len(list(root.rglob("*.html")))
    print(f"{pages} pages, {len(bad)} broken internal links")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
