"""IOC start shortcuts: lean FastCS imports and softioc's field checks done once.

Both change library state of the process (imports, softioc's record set), so
each check runs in a fresh Python process.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from .conftest import loopback_env

pytestmark = pytest.mark.e2e


def _run(code: str) -> str:
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        env=loopback_env(),
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_lean_imports_leave_out_unused_transports_only_while_importing() -> None:
    out = _run(
        """
        import sys
        import setuptools_dso.runtime as runtime
        before = runtime._auto_pkg
        from fastcs_ethercat.ioc.fastcs_adapter import import_ioc_modules
        import_ioc_modules()
        print("ca", "softioc" in sys.modules, "p4p" in sys.modules)
        print("rest", "fastcs.transports.rest" in sys.modules, "fastapi" in sys.modules)
        print("restored", runtime._auto_pkg is before)
        import fastcs.transports.rest.transport  # still there when asked for
        print("rest later", "fastapi" in sys.modules)
        """
    )
    assert out.split("\n")[:4] == [
        "ca True True",
        "rest False False",
        "restored True",
        "rest later True",
    ]


_BAD_FIELDS = """
from softioc import builder

def errors(tag):
    found = []
    for name, fields in [
        ("aIn", {"SCAN": "bogus"}),
        ("aIn", {"PREC": "abc"}),
        ("aIn", {"NOTAFIELD": 1}),
        ("mbbIn", {"ZRST": "a" * 50}),
        ("longOut", {"DRVH": "x"}),
    ]:
        try:
            getattr(builder, name)(f"T:{tag}:{len(found)}", **fields)
            found.append("accepted")
        except Exception as error:
            found.append(f"{type(error).__name__}: {error}")
    return found
"""


def test_field_checks_raise_the_library_errors_and_accept_repeats() -> None:
    out = _run(
        _BAD_FIELDS
        + textwrap.dedent(
            """
        from fastcs_ethercat.ioc.fastcs_adapter import install_field_memo
        library = errors("lib")
        install_field_memo()
        install_field_memo()  # idempotent
        assert errors("memo") == library, (errors("again"), library)
        assert errors("again") == library  # failures are never remembered
        for index in range(50):  # repeated and new values of one record type
            builder.aIn(f"T:OK:{index}", EGU="mm", PREC=3, DESC=f"point {index}")
            builder.boolIn(f"T:B:{index}", ZNAM="off", ONAM="on")
        print("\\n".join(library))
        """
        )
    )
    assert out.splitlines() == [
        'AssertionError: Can\'t write "bogus" to field SCAN: Not a valid menu choice',
        'AssertionError: Can\'t write "abc" to field PREC: Not a valid integer',
        "AttributeError: Invalid field name NOTAFIELD",
        "AssertionError: Can't write \"" + "a" * 50 + '" to field ZRST: String'
        " too long, max 25 characters",
        'AssertionError: Can\'t write "x" to field DRVH: Not a valid integer',
    ]


def test_quick_db_text_writes_what_the_library_writes() -> None:
    """Every character, alone and in text, is quoted as epicsdbbuilder
    quotes it, and records (comments, links, aliases, infos, fields of any
    length) are written as its `Record.Print` writes them."""
    out = _run(
        """
        import io
        from epicsdbbuilder import recordbase
        from softioc import builder
        from fastcs_ethercat.ioc.fastcs_adapter import install_quick_db_text
        library = recordbase.quote_string
        values = [chr(code) for code in range(300)] + [
            "", "plain text", 'a "quoted" word', "back\\\\slash", "tab\\there",
            "Grad \\u00b0C", "line\\nbreak",
        ]
        builder.SetDeviceName("QUICK")
        source = builder.aIn("SOURCE", EGU='m"m', DESC="tab\\there", PREC=3)
        calc = builder.records.calc("CALC", CALC="A+1", INPA=source)
        calc.add_alias("QUICK:OTHER")
        calc.add_alias("QUICK:ANOTHER")
        calc.add_comment("a comment")
        calc.add_metadata("some metadata")
        calc.add_info("Q:form", "String")
        builder.mbbIn("STATES", ("one", 0), ("two \\"2\\"", 1))
        builder.WaveformOut("WAVE", length=5, FTVL="CHAR")
        records = list(recordbase.recordset._RecordSet__RecordSet.values())

        def text():
            out = io.StringIO()
            for record in records:
                record.Print(out)
            return out.getvalue()

        printed = text()
        install_quick_db_text()
        install_quick_db_text()  # idempotent
        quick = recordbase.quote_string
        print(quick is not library)
        print(all(quick(value) == library(value) for value in values))
        print(text() == printed, "alias" in printed and "info(" in printed)
        """
    )
    assert out.split() == ["True", "True", "True", "True"]


def test_lean_imports_leave_shell_gui_and_setuptools_for_later() -> None:
    """IPython, pvi, setuptools, prompt_toolkit and ruamel.yaml (FastCS's
    YAML launcher) are not imported at start; what FastCS took from them
    imports them when called, and they import as usual."""
    out = _run(
        """
        import sys
        from fastcs_ethercat.ioc.fastcs_adapter import import_ioc_modules
        import_ioc_modules()
        unused = ("IPython", "pvi", "setuptools", "prompt_toolkit", "ruamel")
        print(*(name in sys.modules for name in unused))
        import fastcs
        launch = fastcs.launch
        from fastcs.launch import launch as real_launch
        print(launch.__name__, real_launch.__module__, "ruamel" in sys.modules)
        from fastcs.logging import _logging
        proxy = _logging.StdoutProxy(raw=True)
        print(type(proxy).__module__)
        proxy.close()
        from fastcs.transports.epics.ca import transport
        from fastcs.controllers import Controller
        controller = Controller()
        controller.set_path(["LEAN"])
        gui = transport.EpicsGUI(controller.create_api_and_tasks()[0])
        print(type(gui).__module__, "pvi" in sys.modules)
        import setuptools_dso
        print(callable(setuptools_dso.setup), callable(setuptools_dso.find_dso))
        """
    )
    assert out.splitlines() == [
        "False False False False False",
        "launch fastcs.launch True",
        "prompt_toolkit.patch_stdout",
        "fastcs.transports.epics.gui True",
        "True True",
    ]


def test_the_ioc_gives_up_realtime_scheduling_before_epics_starts() -> None:
    """As root EPICS would run its threads SCHED_FIFO and lock all memory."""
    out = _run(
        """
        from pathlib import Path
        from fastcs_ethercat.ioc.fastcs_adapter import import_ioc_modules
        from fastcs_ethercat.ioc.scheduling import CAP_SYS_NICE
        import_ioc_modules()
        text = Path("/proc/self/status").read_text()
        status = dict(line.split(":", 1) for line in text.splitlines())
        print(int(status["CapEff"], 16) >> CAP_SYS_NICE & 1, status["VmLck"].split()[0])
        """
    )
    assert out.split() == ["0", "0"]


def test_the_collector_runs_rarely_and_freezes_what_the_start_built() -> None:
    """From the IOC's start a young collection waits for `GC_THRESHOLD`
    objects (the collector still runs); the tree's burst pauses it; once
    serving, what was built is frozen out of its sight and it runs again."""
    out = _run(
        """
        import gc
        from fastcs_ethercat import collector
        collector.collect_rarely()
        print(gc.get_threshold()[0] == collector.GC_THRESHOLD, gc.isenabled())
        collector.pause()
        print(gc.isenabled())
        built = [[position] for position in range(1000)]
        frozen = gc.get_freeze_count()
        collector.settle_garbage_collector()
        print(gc.get_freeze_count() - frozen >= len(built))
        print(gc.get_threshold()[0] == collector.GC_THRESHOLD, gc.isenabled())
        """
    )
    assert out.split() == ["True", "True", "False", "True", "True", "True"]


def test_pva_scalar_types_are_built_once_per_kind_and_match_fastcs() -> None:
    out = _run(
        """
        from fastcs.attributes import AttrR, AttrRW
        from fastcs.datatypes import Bool, Float, Int, String
        from fastcs.transports.epics.pva import _pv_handlers, types
        built = types.make_p4p_type
        from fastcs_ethercat.ioc.fastcs_adapter import install_p4p_type_memo
        install_p4p_type_memo()
        install_p4p_type_memo()  # idempotent: no memo of the memo
        make = types.make_p4p_type
        print("shared", make is _pv_handlers.make_p4p_type, make is not built)
        kinds = [Bool(), Float(prec=3), Int(units="mm"), String()]
        for kind in kinds:
            for attr in (AttrR, AttrRW):
                a, b = attr(kind), attr(type(kind)())
                same = make(a) is make(b)
                equal = make(a).aspy() == built(a).aspy()
                print(type(kind).__name__, attr.__name__, same, equal)
        print("kinds differ", make(AttrR(Int())) is not make(AttrRW(Int())))
        """
    )
    lines = out.split("\n")
    assert lines[0] == "shared True True"
    assert all(line.endswith("True True") for line in lines[1:9]), out
    assert lines[9] == "kinds differ True"


def test_records_count_as_initialised_once_the_last_scan_list_is_built() -> None:
    """iocInit calls Python for every I/O Intr record's scan list after the
    records' init hook; the PVA build waits for the last call, not the hook
    (else both share the GIL and iocBuild's sleep starts late), and starts
    while iocInit still sleeps."""
    out = _run(
        """
        import asyncio
        from softioc import asyncio_dispatcher, builder, imports, softioc
        from fastcs_ethercat.ioc import fastcs_adapter

        builder.SetDeviceName("SCANLISTS")
        for index in range(40):
            builder.aIn(f"IN{index}")
            builder.longOut(f"OUT{index}")
        builder.longIn("PASSIVE", SCAN="Passive")
        built = []
        library = imports.scanIoInit

        def counted(scan_list):
            built.append(scan_list)
            library(scan_list)

        imports.scanIoInit = counted

        async def main():
            loop = asyncio.get_running_loop()
            records = fastcs_adapter.watch_records_initialised(loop)
            builder.LoadDatabase()
            dispatcher = asyncio_dispatcher.AsyncioDispatcher()
            init = asyncio.ensure_future(
                asyncio.to_thread(softioc.iocInit, dispatcher)
            )
            await records
            print("at resolve", len(built), init.done())
            await init
            print("after iocInit", len(built))

        asyncio.run(main())
        """
    )
    told = [line for line in out.splitlines() if line.startswith(("at ", "after "))]
    assert told == ["at resolve 40 False", "after iocInit 40"], out
