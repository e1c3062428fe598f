import pytest

from lanelab.atomic_file import atomic_output, partial_path


def test_success_renames_into_place(tmp_path):
    target = tmp_path / "a.bin"
    with atomic_output(target) as tmp:
        assert tmp == partial_path(target) and tmp.name.startswith(".")
        tmp.write_bytes(b"complete")
        assert not target.exists()
    assert target.read_bytes() == b"complete"
    assert not partial_path(target).exists()


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt])
def test_failure_keeps_previous_file_and_removes_temporary(tmp_path, error):
    target = tmp_path / "a.bin"
    target.write_bytes(b"previous")
    with pytest.raises(error):
        with atomic_output(target) as tmp:
            tmp.write_bytes(b"half")
            raise error()
    assert target.read_bytes() == b"previous"
    assert not partial_path(target).exists()


def test_two_processes_writing_one_file_use_two_temporaries(tmp_path):
    """Issue 37, case 9: two lanelab-synth runs into one folder wrote into one temporary."""
    import multiprocessing as mp

    target = tmp_path / "log.mcap"
    with mp.get_context("fork").Pool(1) as pool:
        theirs = pool.apply(partial_path, (target,))
    assert theirs != partial_path(target)
    assert theirs.name.startswith(".log.mcap.") and theirs.name.endswith(".partial")
