"""lenticalib.outputs: output paths checked before work, staged folders, all-or-nothing results."""

import shutil
from pathlib import Path

import pytest

from lenticalib.errors import InputError
from lenticalib.outputs import check_output_file, check_output_folder, restored_on_failure, staged_folder

from .outputs_support import read_only  # noqa: F401 -- pytest fixture


def _tree(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` (hidden ones included) with its bytes (None for folders)."""
    return {str(p.relative_to(folder)): (None if p.is_dir() else p.read_bytes()) for p in sorted(folder.rglob("*"))}


def test_output_file_checks(tmp_path, read_only):
    (tmp_path / "old.json").write_text("{}")
    assert check_output_file(tmp_path / "old.json", "profile") == tmp_path / "old.json"  # replaced later
    assert check_output_file(tmp_path / "new.json", "profile") == tmp_path / "new.json"
    cases = {
        tmp_path: "is a folder",
        tmp_path / "missing" / "deeper" / "p.json": "does not exist",
        tmp_path / "old.json" / "p.json": "is not a folder",
        read_only(tmp_path / "ro") / "p.json": "not writable",
    }
    for path, fragment in cases.items():
        with pytest.raises(InputError) as info:
            check_output_file(path, "profile")
        assert fragment in str(info.value) and "profile" in str(info.value), str(info.value)
    assert not (tmp_path / "missing").exists()  # a missing parent is never created


def test_output_folder_checks(tmp_path, read_only):
    (tmp_path / "file").write_text("x")
    report = tmp_path / "report"
    report.mkdir()
    (report / "panel.png").write_bytes(b"png")
    assert check_output_folder(report, "report", contents={"panel.png"}) == report
    assert check_output_folder(tmp_path / "new", "report") == tmp_path / "new"
    (report / "thesis.tex").write_text("my work")
    cases = {
        tmp_path / "file": "is a file",
        tmp_path / "missing" / "report": "does not exist",
        read_only(tmp_path / "ro"): "not writable",
        read_only(tmp_path / "ro2") / "report": "not writable",
    }
    for path, fragment in cases.items():
        with pytest.raises(InputError) as info:
            check_output_folder(path, "report")
        assert fragment in str(info.value), str(info.value)
    with pytest.raises(InputError) as info:
        check_output_folder(report, "report", contents={"panel.png"})
    assert str(info.value).startswith(f"{report}: holds 'thesis.tex'"), str(info.value)


def test_staged_folder_replaces_only_when_complete(tmp_path):
    target = tmp_path / "report"
    with staged_folder(target, "report", ("a.txt", "b.txt")) as stage:
        assert stage.parent == tmp_path and stage.name.startswith(".report.") and not target.exists()
        (stage / "a.txt").write_text("first")
    assert _tree(tmp_path) == {"report": None, "report/a.txt": b"first"}

    with pytest.raises(RuntimeError):
        with staged_folder(target, "report", ("a.txt", "b.txt")) as stage:
            (stage / "a.txt").write_text("half")
            raise RuntimeError("the work failed")
    assert _tree(tmp_path) == {"report": None, "report/a.txt": b"first"}  # old intact, nothing hidden left

    with staged_folder(target, "report", ("a.txt", "b.txt")) as stage:
        (stage / "b.txt").write_text("second")
    assert _tree(tmp_path) == {"report": None, "report/b.txt": b"second"}


def test_staged_folder_refuses_before_the_work(tmp_path):
    ran = []
    with pytest.raises(InputError):
        with staged_folder(tmp_path / "missing" / "report", "report", ()):
            ran.append(True)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(InputError):
        with staged_folder(tmp_path / "mine", "report", contents={"panel.png"}):
            ran.append(True)
    assert ran == [] and _tree(tmp_path) == {"mine": None, "mine/notes.txt": b"keep"}


@pytest.mark.parametrize("earlier", [True, False], ids=["earlier-results", "fresh"])
def test_restored_on_failure_is_all_or_nothing(tmp_path, earlier):
    folder, result = tmp_path / "captures", tmp_path / "truth.json"
    if earlier:
        folder.mkdir()
        (folder / "a.jpg").write_bytes(b"old photo")
        result.write_text("old truth")
    before = _tree(tmp_path)

    for exc in (RuntimeError("failed"), KeyboardInterrupt()):
        with pytest.raises(type(exc)):
            with restored_on_failure([folder, result]):
                assert folder.exists() == result.exists() == earlier  # the body sees the earlier ones
                folder.mkdir(exist_ok=True)
                (folder / "b.jpg").write_bytes(b"half")
                if earlier:
                    (folder / "a.jpg").write_bytes(b"overwritten")
                    result.write_text("half truth")
                raise exc
        assert _tree(tmp_path) == before

    with restored_on_failure([folder, result]):
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir()
        (folder / "b.jpg").write_bytes(b"new photo")
        result.write_text("new truth")
    assert _tree(tmp_path) == {"captures": None, "captures/b.jpg": b"new photo", "truth.json": b"new truth"}
