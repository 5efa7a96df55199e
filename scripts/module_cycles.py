#!/usr/bin/env python3
"""Prints the import cycles among a crate's top-level modules (`use crate::NAME` between the
files under SRC) and exits 1 if there is one: scripts/check_layering.sh holds the pipeline to
none, so its stages, errors and time helpers stay leaves and layers."""
import os
import re
import sys


def module_of(src, path):
    first = os.path.relpath(path, src).split(os.sep)[0]
    return first[:-3] if first.endswith(".rs") else first


def imports(src):
    graph = {}
    for directory, _, files in os.walk(src):
        for name in files:
            path = os.path.join(directory, name)
            if not name.endswith(".rs") or path in (f"{src}/main.rs", f"{src}/lib.rs"):
                continue
            text = re.sub(r"//.*", "", open(path, encoding="utf-8").read())
            used = set(re.findall(r"crate::(\w+)", text))
            for group in re.findall(r"crate::\{([^;]*)\}", text, re.S):
                used |= set(re.findall(r"(?:^|[,{]\s*)(\w+)", group))
            module = module_of(src, path)
            graph.setdefault(module, set()).update(used - {module})
    return {module: {m for m in used if m in graph} for module, used in graph.items()}


def cycles(graph):
    """Tarjan's strongly connected components with more than one module."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in graph[node]:
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while not component or component[-1] != node:
                component.append(stack.pop())
                on_stack.discard(component[-1])
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


if __name__ == "__main__":
    found = cycles(imports(sys.argv[1]))
    for component in found:
        print(f"{sys.argv[1]}: modules import one another in a circle: {' '.join(component)}")
    sys.exit(1 if found else 0)
