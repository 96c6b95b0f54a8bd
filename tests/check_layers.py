#!/usr/bin/env python3
"""Checks every project #include against the layer table in docs/architecture.md.

The table (rows "| `folder/` | `a/`, `b/` | ... |" under the heading "## Layers") says which folders each
folder may include; an include of any other project folder is a layering violation and fails the test,
so an upward arrow is caught by CI, not by a reviewer. Generated protobuf headers ("bistable.pb.h",
"bistable.grpc.pb.h") count as the folder proto/.
Usage: check_layers.py REPO_ROOT

With --targets FILE --cxx COMPILER it checks instead what the compiler sees (cmake/layers.cmake): FILE has a
line "folder target dir|dir|..." per layer target with the target's include directories; for each, a header
of every folder of the table is looked up (__has_include) with those directories. One of a folder not on the
target's row must not be found, one of its own folder must.
"""
import os
import re
import subprocess
import sys
import tempfile

root = sys.argv[1] if len(sys.argv) > 1 and not sys.argv[1].startswith("--") else \
    os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
doc = open(os.path.join(root, "docs", "architecture.md"), encoding="utf-8").read()
section = doc.split("## Layers", 1)[1].split("\n## ", 1)[0]
allowed = {}
for line in section.splitlines():
    m = re.match(r"\|\s*`([a-z_]+)/`\s*\|([^|]*)\|", line)
    if m:
        allowed[m.group(1)] = set(re.findall(r"`([a-z_]+)/`", m.group(2))) | {m.group(1)}
if not allowed:
    sys.exit("no layer table found under '## Layers' in docs/architecture.md")


def check_targets(targets_file, cxx):
    """The compiler's view: every layer target finds its own folder's headers and none off its row."""
    probe = {}  # folder -> one of its headers, as included
    for folder in sorted(allowed):
        headers = sorted(f for f in os.listdir(os.path.join(root, folder)) if f.endswith(".h"))
        if headers:
            probe[folder] = f"{folder}/{headers[0]}"
    source = "".join(f'#if __has_include("{h}")\nfound {folder}\n#endif\n' for folder, h in probe.items())
    bad, lines = [], 0
    empty = tempfile.mkdtemp()  # the working directory: "..." includes of standard input are looked up there first
    for line in open(targets_file, encoding="utf-8"):
        if not line.strip():
            continue
        folder, target, dirs = line.split(" ", 2)
        flags = [f"-I{d}" for d in dirs.strip().split("|") if d]
        out = subprocess.run([cxx, "-std=c++20", "-E", "-P", "-x", "c++", "-", *flags], input=source, text=True,
                             capture_output=True, check=True, cwd=empty).stdout
        found = set(re.findall(r"^found (\w+)$", out, re.M))
        lines += 1
        if folder not in found:
            bad.append(f"{target} ({folder}/): its own {probe[folder]} is not found")
        for other in sorted(found - allowed[folder]):
            bad.append(f"{target} ({folder}/): finds {probe[other]} ({other}/ is not on {folder}/'s row)")
    os.rmdir(empty)
    for b in bad:
        print(b)
    print(f"layers: {lines} targets' include paths checked against {len(probe)} folders, {len(bad)} violations")
    sys.exit(1 if bad or not lines else 0)


if "--targets" in sys.argv:
    check_targets(sys.argv[sys.argv.index("--targets") + 1], sys.argv[sys.argv.index("--cxx") + 1])

include = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
violations, checked = [], 0
for folder in sorted(allowed):
    for dirpath, _, files in os.walk(os.path.join(root, folder)):
        for f in files:
            if not f.endswith((".h", ".cc")):
                continue
            path = os.path.join(dirpath, f)
            for n, line in enumerate(open(path, encoding="utf-8", errors="replace"), 1):
                m = include.match(line)
                if not m:
                    continue
                target = m.group(1)
                dep = "proto" if target.startswith("bistable.") else target.split("/", 1)[0] if "/" in target else None
                if dep is None:
                    continue
                checked += 1
                if dep in allowed and dep not in allowed[folder]:
                    violations.append(f"{os.path.relpath(path, root)}:{n}: {folder}/ includes {target} ({dep}/ is not below {folder}/)")
                elif dep not in allowed:
                    violations.append(f"{os.path.relpath(path, root)}:{n}: {target}: folder {dep}/ is not in the layer table")
for v in violations:
    print(v)
print(f"layers: {checked} project includes in {len(allowed)} folders checked, {len(violations)} violations")
sys.exit(1 if violations else 0)
