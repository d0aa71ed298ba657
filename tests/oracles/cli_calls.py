"""The command line called in-process, as the tests of several packages call it."""

from __future__ import annotations

from rcm_kin.cli import main


def run(capsys, *argv):
    """``rcm-kin argv...`` in this process: (exit status, stdout, stderr)."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(capsys, argv, message):
    """``argv`` fails with status 2, nothing on stdout, one ``error:`` line containing ``message``."""
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == "", (argv, out, err)
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    assert message in err, err
