#!/usr/bin/env python3
"""Checks every project #include against the layer table in docs/architecture.md.

The table (rows "| `folder/` | `a/`, `b/` | ... |" under the heading "## Layers") says which folders each
folder may include; an include of any other project folder is a layering violation and fails the test,
so an upward arrow is caught by CI, not by a reviewer. Generated protobuf headers ("bistable.pb.h",
"bistable.grpc.pb.h") count as the folder proto/.
Usage: check_layers.py REPO_ROOT
"""
import os
import re
import sys

root = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
doc = open(os.path.join(root, "docs", "architecture.md"), encoding="utf-8").read()
section = doc.split("## Layers", 1)[1].split("\n## ", 1)[0]
allowed = {}
for line in section.splitlines():
    m = re.match(r"\|\s*`([a-z_]+)/`\s*\|([^|]*)\|", line)
    if m:
        allowed[m.group(1)] = set(re.findall(r"`([a-z_]+)/`", m.group(2))) | {m.group(1)}
if not allowed:
    sys.exit("no layer table found under '## Layers' in docs/architecture.md")

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
