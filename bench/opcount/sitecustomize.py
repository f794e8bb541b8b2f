"""Counts the Python opcodes a bench server's main thread runs (its event loop: the bridge's, or a ceiling's), for
bench/suite.py's opcodes section. On this directory's PYTHONPATH, it does so only in the process whose script is
named by BENCH_OPCODES_OF (roslaunch, which starts the bridge, passes the environment on and is not counted), and
writes the count so far to the file BENCH_OPCODES names on SIGUSR2. Unlike CPU time, the count is the same from run
to run, whatever else the machine does."""

import os
import sys

if os.environ.get("BENCH_OPCODES") and os.path.basename(sys.argv[0]) == os.environ.get("BENCH_OPCODES_OF"):
    import _thread
    import signal

    _count = 0

    if hasattr(sys, "monitoring"):  # (Python 3.12 on: a tracer set this early sees no opcode events there)
        _main = _thread.get_ident()  # (monitoring sees every thread; a tracer only the one that set it)

        def _instruction(code, offset):
            global _count
            if _thread.get_ident() == _main:
                _count += 1

        _tool, _events = sys.monitoring.PROFILER_ID, sys.monitoring.events
        sys.monitoring.use_tool_id(_tool, "bench opcount")
        sys.monitoring.register_callback(_tool, _events.INSTRUCTION, _instruction)
        sys.monitoring.set_events(_tool, _events.INSTRUCTION)
    else:

        def _trace(frame, event, arg):
            global _count
            if event == "opcode":
                _count += 1
            else:  # (a frame's first event: from then on its opcodes, not its lines)
                frame.f_trace_lines, frame.f_trace_opcodes = False, True
            return _trace

        sys.settrace(_trace)

    def _write(*_):
        path = os.environ["BENCH_OPCODES"]
        with open(path + ".part", "w") as out:
            out.write(str(_count))
        os.replace(path + ".part", path)  # (the bench reads it once it is whole)

    signal.signal(signal.SIGUSR2, _write)
