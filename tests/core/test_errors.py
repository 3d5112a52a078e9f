"""`core.errors.warnings_held`: a reader's log records shown once it returns, in order, and dropped where it refuses
its file; another thread's records pass as they come."""

import logging
import threading

import pytest

from core.errors import InputError, warnings_held


@warnings_held
def _read(refuse: bool, log_name: str = "formats.reader"):
    log = logging.getLogger(log_name)
    log.warning("first, a warning")
    log.info("second, a note")
    if refuse:
        raise InputError("the file is refused")
    return "read"


def test_a_readers_records_come_in_order_once_and_not_at_all_when_it_refuses(caplog):
    with caplog.at_level(logging.INFO):
        assert _read(False) == "read"
    assert [r.getMessage() for r in caplog.records] == ["first, a warning", "second, a note"]
    caplog.clear()
    with caplog.at_level(logging.INFO), pytest.raises(InputError):
        _read(True)
    assert caplog.records == []


def test_another_threads_records_pass_while_a_reader_holds_its_own(caplog):
    """A warning of another thread, logged while a reader holds its records and then refuses its file, is not
    dropped with them; a reader's refusal in another thread drops its own warnings only."""
    holding, logged = threading.Event(), threading.Event()

    @warnings_held
    def slow_refusal():
        logging.getLogger("formats.slow").warning("about the refused file")
        holding.set()
        logged.wait(5)
        raise InputError("refused")

    def other():
        holding.wait(5)
        logging.getLogger("core.other").warning("another thread's warning")
        try:
            _read(True, "formats.other_reader")
        except InputError:
            pass
        logged.set()

    with caplog.at_level(logging.WARNING):
        thread = threading.Thread(target=other)
        thread.start()
        with pytest.raises(InputError):
            slow_refusal()
        thread.join()
    assert [r.getMessage() for r in caplog.records] == ["another thread's warning"]
