"""The tools' one exit for bad input (STYLE.md): a one-line message naming the tool, the file or option, and the
problem, on stderr, and exit code 2. A tool binds its name once: `fail = functools.partial(input_error, "name")`."""
import sys


def input_error(tool, path, problem):
    print(f"{tool}: {path}: {problem}", file=sys.stderr)
    sys.exit(2)
