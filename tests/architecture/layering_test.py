#!/usr/bin/env python3
"""The library's layers depend only downwards, the library knows nothing of the service, and the
client library and the server do not include each other (the CLI, in cli/, sits above both).

Every #include "mlsreg/<layer>/..." in lib/include/mlsreg/<layer>/ and lib/src/<layer>/ must name
the same layer or one it may use (lib/CMakeLists.txt); lib/ may not include the wire, the
protocol, the server or the client. Prints each offending include and exits 1.
"""
import pathlib
import re
import sys

# What each layer may include (itself included); mirrors MLSREG_LAYER_DEPS in lib/CMakeLists.txt,
# closed transitively.
ALLOWED = {
    "core": {"core"},
    "io": {"core", "io"},
    "geometry": {"core", "geometry"},
    "solvers": {"core", "solvers"},
    "correspondences": {"core", "geometry", "correspondences"},
    "registration": {"core", "geometry", "correspondences", "solvers", "registration"},
    "evaluation": {"core", "io", "geometry", "correspondences", "solvers", "registration",
                   "evaluation"},
    "multiview": {"core", "geometry", "correspondences", "solvers", "registration", "multiview"},
}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def main(root: pathlib.Path) -> int:
    problems = []
    lib = root / "lib"
    for layer, allowed in ALLOWED.items():
        for folder in (lib / "include" / "mlsreg" / layer, lib / "src" / layer):
            if not folder.is_dir():
                problems.append(f"{folder}: missing layer folder")
                continue
            for path in sorted(folder.rglob("*")):
                if path.suffix not in (".h", ".cc"):
                    continue
                for target in INCLUDE.findall(path.read_text()):
                    parts = target.split("/")
                    if parts[0] in ("server", "client") or target.startswith(
                            ("mlsreg/wire/", "mlsreg/v1/", "mlsreg/client/", "grpc")):
                        problems.append(f"{path.relative_to(root)}: includes {target} (the library "
                                        "knows nothing of the service)")
                    elif parts[0] == "mlsreg" and len(parts) == 3 and parts[1] not in allowed:
                        problems.append(f"{path.relative_to(root)}: {layer} includes {target}, a "
                                        f"layer above it (allowed: {', '.join(sorted(allowed))})")
                    elif parts[0] == "mlsreg" and len(parts) == 2:
                        problems.append(f"{path.relative_to(root)}: includes {target}, which is in "
                                        "no layer")
    # The client library and the server are peers over the wire: neither includes the other.
    for peer, other in (("client", "server/"), ("server", "mlsreg/client/")):
        for path in sorted((root / peer).rglob("*")):
            if path.suffix in (".h", ".cc"):
                for target in INCLUDE.findall(path.read_text()):
                    if target.startswith(other):
                        problems.append(f"{path.relative_to(root)}: includes {target}")
    for p in problems:
        print(p)
    print(f"layering: {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()))
