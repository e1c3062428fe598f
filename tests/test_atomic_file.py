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
