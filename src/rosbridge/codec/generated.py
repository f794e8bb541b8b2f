"""Running the Python source the converters generate per message type. Each piece gets a file name of its own,
and its lines go into linecache, so that a traceback through a generated reader or packer shows the line that
failed instead of nothing."""

import itertools
import linecache

_numbers = itertools.count()


def define(source, namespace, what):
    """Runs `source` (function definitions) in `namespace`; `what` names it in tracebacks (e.g. the type)."""
    filename = f"<rosbridge generated {next(_numbers)}: {what}>"
    linecache.cache[filename] = (len(source), None, source.splitlines(keepends=True), filename)
    exec(compile(source, filename, "exec"), namespace)
