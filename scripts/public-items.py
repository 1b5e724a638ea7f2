"""Counts the library's public declarations as written: `pub` items (not `pub(crate)` or
`pub(super)`) and public fields in src/ outside the command line (src/cli/, src/main.rs).
Each is counted where its module puts it: the public API, behind the `internals` feature
(the module, or the item, is public only with it), or private in effect (a `pub` item in a
module that is not public). Usage: python3 scripts/public-items.py [ROOT]"""
import pathlib
import re
import sys

root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".") / "src"
KINDS = {
    "functions": r"pub (const |async |unsafe )*fn ",
    "types": r"pub (struct|enum|trait|type|union) ",
    "constants": r"pub (const|static) [A-Z_0-9]+",
    "modules": r"pub mod ",
    "re-exports": r"pub use ",
    "fields": r"pub [a-z_][a-z_0-9]*: ",
}
MOD = re.compile(r"^\s*(pub(\([a-z]+\))?\s+)?mod (\w+);")


def attributes(lines, i):
    """The attribute and doc lines right above line i, joined."""
    j, out = i - 1, []
    while j >= 0 and lines[j].strip().startswith(("#[", "//")):
        out.append(lines[j])
        j -= 1
    return " ".join(out)


def module_of(path):
    rel = path.relative_to(root).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("lib", "mod"):
        parts.pop()
    return tuple(parts)


files = {module_of(p): p for p in root.rglob("*.rs")}
# Each module's visibility in its parent: "public", "internals", "private" or "test".
declared = {}
for module, path in files.items():
    lines = path.read_text().splitlines()
    for i, line in enumerate(lines):
        m = MOD.match(line)
        if not m:
            continue
        attrs = attributes(lines, i)
        child = module + (m.group(3),)
        if "cfg(test)" in attrs:
            vis = "test"
        elif m.group(1) and not m.group(2):
            vis = "internals" if '"internals"' in attrs else "public"
        else:
            vis = "private"
        # A module declared twice under cfgs (public with the feature, private without) is
        # internal; otherwise its most visible declaration counts.
        order = ["test", "private", "internals", "public"]
        old = declared.get(child, "test")
        if {old, vis} == {"private", "internals"}:
            declared[child] = "internals"
        elif order.index(vis) > order.index(old):
            declared[child] = vis


def standing(module):
    worst = "public"
    for n in range(1, len(module) + 1):
        vis = declared.get(module[:n], "private")
        if vis in ("private", "test"):
            return "private"
        if vis == "internals":
            worst = "internals"
    return worst


counts = {s: dict.fromkeys(KINDS, 0) for s in ("public", "internals", "private")}
for module, path in sorted(files.items()):
    if module[:1] == ("cli",) or module == ("main",):
        continue
    where = standing(module)
    lines = path.read_text().splitlines()
    for i, line in enumerate(lines):
        text = line.strip()
        for kind, pattern in KINDS.items():
            if re.match(pattern, text) and (kind != "fields" or line.startswith(" ")):
                item = where
                if item == "public" and '"internals"' in attributes(lines, i):
                    item = "internals"
                counts[item][kind] += 1
                break
for where, c in counts.items():
    print(f"{where}: " + ", ".join(f"{k} {v}" for k, v in c.items()) + f"; total {sum(c.values())}")
