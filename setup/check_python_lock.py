"""Checks the Python lock (postprocess/requirements.lock, written by `make python-lock`).

  check_python_lock.py REQUIREMENTS LOCK   every package REQUIREMENTS names is pinned in LOCK,
                                           at the version REQUIREMENTS pins
  check_python_lock.py --installed LOCK    every package of this environment (pip freeze) is
                                           pinned in LOCK at the version installed

Exit status 1 with the differences and the command that fixes them. Standard library only: the
first check runs before the environment exists."""
import re
import subprocess
import sys


def canonical(name):
    return re.sub(r"[-_.]+", "-", name).lower()


def pins(lines):
    """{name: version or None} of requirement lines (comments and options skipped)."""
    found = {}
    for line in lines:
        line = line.split("#", 1)[0].strip()
        if not line or line.startswith("-"):
            continue
        match = re.match(r"([A-Za-z0-9][A-Za-z0-9._-]*)(\[[^]]*\])?\s*(==\s*([^;\s]+))?", line)
        if match:
            found[canonical(match.group(1))] = match.group(4)
    return found


def main(arguments):
    fix = "run 'make python-lock' and commit postprocess/requirements.lock"
    if arguments[0] == "--installed":
        with open(arguments[1]) as f:
            lock = pins(f)
        frozen = subprocess.run([sys.executable, "-m", "pip", "freeze"], capture_output=True, text=True,
                                check=True).stdout.splitlines()
        problems = [f"{name}=={version} is installed, the lock has {lock.get(name) or 'no pin'}"
                    for name, version in pins(frozen).items() if lock.get(name) != version]
    else:
        with open(arguments[0]) as f:
            wanted = pins(f)
        with open(arguments[1]) as f:
            lock = pins(f)
        problems = [f"{name} is not pinned" if name not in lock else f"{name}: {arguments[0]} pins {version}, "
                    f"the lock {lock[name]}"
                    for name, version in wanted.items()
                    if name not in lock or (version is not None and lock[name] != version)]
    for problem in problems:
        print(f"{arguments[-1]}: {problem}", file=sys.stderr)
    if problems:
        print(f"{arguments[-1]} does not match: {fix}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
