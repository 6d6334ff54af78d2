#!/usr/bin/env python3
"""Every command module of the `axcomp` CLI is a leaf: it imports no other command module and not the
dispatcher (`commands`); what commands share lives in `cli` (argument types) and `commands::common`
(helpers), which import no command.

Usage: command_leaves.py [SRC_DIR]   (default host-tools/src)

Uses the import graph of .ci/import_cycles.py (`use` lines and inline `crate::`/`super::` paths, test
modules left out). Prints each import of one command by another and exits 1 if there is one that is not
a known exception (KNOWN below: imports being moved into libraries; delete an entry once it is gone).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import import_cycles  # noqa: E402

# Modules every command may import (they import no command): the helpers, and the argument types and
# output of the `diagnose` family (one command with a module per data kind).
SHARED = {("commands", "common"), ("commands", "diagnose_shared")}

# Known imports between command modules, to be removed (importer, imported). None today.
KNOWN = set()


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else "host-tools/src"
    _, edges = import_cycles.graph(src)
    bad, known = [], []
    for m in sorted(edges):
        if len(m) != 2 or m[0] != "commands" or m in SHARED:
            continue
        for t in sorted(edges[m]):
            if t[:1] != ("commands",) or t in SHARED:
                continue
            edge = (m[1], "::".join(t[1:]) or "commands")
            (known if edge in KNOWN else bad).append(edge)
    for a, b in known:
        print(f"known: commands::{a} imports commands::{b}")
    for a, b in bad:
        print(f"commands::{a} imports commands::{b}: a command imports no other command", file=sys.stderr)
    shared_bad = [
        (s, t) for s in SHARED for t in edges.get(s, ()) if t[:1] == ("commands",) and t not in SHARED
    ] + [(("cli",), t) for t in edges.get(("cli",), ()) if t[:1] == ("commands",)]
    for s, t in shared_bad:
        print(f"{'::'.join(s)} imports {'::'.join(t)}: a shared module imports no command", file=sys.stderr)
    print(f"{src}: {len(bad) + len(shared_bad)} import(s) of a command by a command or shared module, "
          f"{len(known)} known")
    return 1 if bad or shared_bad else 0


if __name__ == "__main__":
    sys.exit(main())
