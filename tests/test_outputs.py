"""lenticalib.outputs: output paths checked before work, staged folders, all-or-nothing results."""

import os
import shutil
from pathlib import Path

import pytest

from lenticalib.core.errors import InputError
from lenticalib.core.files.outputs import check_output_file, check_output_folder, restored_on_failure, staged_folder

from .outputs_support import read_only  # noqa: F401 -- pytest fixture


def _tree(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` (hidden ones included) with its bytes (None for folders)."""
    return {str(p.relative_to(folder)): (None if p.is_dir() else p.read_bytes()) for p in sorted(folder.rglob("*"))}


def test_output_file_checks(tmp_path, read_only):
    (tmp_path / "old.json").write_text("{}")
    assert check_output_file(tmp_path / "old.json", "profile", inputs=()) == tmp_path / "old.json"  # replaced later
    assert check_output_file(tmp_path / "new.json", "profile", inputs=()) == tmp_path / "new.json"
    cases = {
        tmp_path: "is a folder",
        tmp_path / "missing" / "deeper" / "p.json": "does not exist",
        tmp_path / "old.json" / "p.json": "is not a folder",
        read_only(tmp_path / "ro") / "p.json": "not writable",
    }
    for path, fragment in cases.items():
        with pytest.raises(InputError) as info:
            check_output_file(path, "profile", inputs=())
        assert fragment in str(info.value) and "profile" in str(info.value), str(info.value)
    assert not (tmp_path / "missing").exists()  # a missing parent is never created


def test_output_folder_checks(tmp_path, read_only):
    (tmp_path / "file").write_text("x")
    os.mkfifo(tmp_path / "pipe")
    report = tmp_path / "report"
    report.mkdir()
    (report / "panel.png").write_bytes(b"png")
    assert check_output_folder(report, "report", contents={"panel.png"}, inputs=()) == report
    assert check_output_folder(tmp_path / "new", "report", inputs=()) == tmp_path / "new"
    (report / "thesis.tex").write_text("my work")
    cases = {
        tmp_path / "file": "is a file, not a folder",
        tmp_path / "pipe": "is a named pipe (FIFO), not a folder",  # once called "a file"
        tmp_path / "missing" / "report": "does not exist",
        read_only(tmp_path / "ro"): "not writable",
        read_only(tmp_path / "ro2") / "report": "not writable",
    }
    for path, fragment in cases.items():
        with pytest.raises(InputError) as info:
            check_output_folder(path, "report", inputs=())
        assert fragment in str(info.value), str(info.value)
    with pytest.raises(InputError) as info:
        check_output_folder(report, "report", contents={"panel.png"}, inputs=())
    assert str(info.value).startswith(f"{report}: holds 'thesis.tex'"), str(info.value)


def test_staged_folder_replaces_only_when_complete(tmp_path):
    target = tmp_path / "report"
    with staged_folder(target, "report", ("a.txt", "b.txt"), inputs=()) as stage:
        assert stage.parent == tmp_path and stage.name.startswith(".report.") and not target.exists()
        (stage / "a.txt").write_text("first")
    assert _tree(tmp_path) == {"report": None, "report/a.txt": b"first"}

    with pytest.raises(RuntimeError):
        with staged_folder(target, "report", ("a.txt", "b.txt"), inputs=()) as stage:
            (stage / "a.txt").write_text("half")
            raise RuntimeError("the work failed")
    assert _tree(tmp_path) == {"report": None, "report/a.txt": b"first"}  # old intact, nothing hidden left

    with staged_folder(target, "report", ("a.txt", "b.txt"), inputs=()) as stage:
        (stage / "b.txt").write_text("second")
    assert _tree(tmp_path) == {"report": None, "report/b.txt": b"second"}


def test_staged_folder_refuses_before_the_work(tmp_path):
    ran = []
    with pytest.raises(InputError):
        with staged_folder(tmp_path / "missing" / "report", "report", (), inputs=()):
            ran.append(True)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(InputError):
        with staged_folder(tmp_path / "mine", "report", contents={"panel.png"}, inputs=()):
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


# ---------------------------------------------------------------------------------------------
# what an output path may name: a regular file, new or existing, or a link to one
# ---------------------------------------------------------------------------------------------

def _nodes(folder: Path) -> dict[str, Path]:
    """Things an output must never replace, made in ``folder`` (never a real device node: a
    character device is made here, as root, with /dev/null's numbers)."""
    import os
    import stat

    folder.mkdir(exist_ok=True)
    fifo = folder / "fifo.json"
    os.mkfifo(fifo)
    nodes = {"fifo": fifo, "folder": folder / "folder.json", "dangling link": folder / "dangling.json",
             "link to /dev/null": folder / "null.json", "link to a FIFO": folder / "to-fifo.json"}
    nodes["folder"].mkdir()
    (nodes["folder"] / "notes.txt").write_text("keep")
    nodes["dangling link"].symlink_to(folder / "nowhere.json")
    nodes["link to /dev/null"].symlink_to("/dev/null")
    nodes["link to a FIFO"].symlink_to(fifo)
    if os.geteuid() == 0:
        nodes["character device"] = folder / "device.json"
        os.mknod(nodes["character device"], 0o600 | stat.S_IFCHR, os.makedev(1, 3))
    return nodes


def _identity(path: Path) -> tuple:
    """What must not change about ``path``: its type, inode and link target (and /dev/null's)."""
    import os

    st = os.lstat(path)
    link = os.readlink(path) if path.is_symlink() else None
    return st.st_mode, st.st_ino, st.st_rdev, link, os.lstat("/dev/null").st_mode, os.lstat("/dev/null").st_rdev


def test_outputs_never_replace_fifos_devices_folders_or_links_to_them(tmp_path):
    from lenticalib.core.files.atomic import write_bytes_atomic

    nodes = _nodes(tmp_path / "nodes")
    before = {name: _identity(path) for name, path in nodes.items()}
    for name, path in nodes.items():
        with pytest.raises(InputError) as info:  # before the work
            check_output_file(path, "profile", inputs=())
        assert str(info.value).startswith(f"{path}: "), (name, str(info.value))
        assert "folder" in str(info.value) or "regular file" in str(info.value) or "does not exist" in str(info.value)
        with pytest.raises(InputError):  # and the write itself, whatever was checked before
            write_bytes_atomic(path, b"{}")
    assert {name: _identity(path) for name, path in nodes.items()} == before
    assert _tree(nodes["folder"]) == {"notes.txt": b"keep"}
    assert not [p for p in (tmp_path / "nodes").iterdir() if p.name.startswith(".")]  # no temporary file left


def test_a_node_appearing_during_the_work_is_not_replaced(tmp_path):
    import os

    from lenticalib.core.files.atomic import PendingFile

    target = tmp_path / "out.json"
    pending = PendingFile(target, "profile")
    pending.write(b"{}")
    os.mkfifo(target)  # made while the work ran
    with pytest.raises(InputError, match="not a regular file"):
        pending.commit()
    assert target.is_fifo() and sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_a_link_to_a_regular_file_is_followed_and_set_id_bits_are_dropped(tmp_path):
    import os

    from lenticalib.core.files.atomic import write_bytes_atomic

    (tmp_path / "real").mkdir()
    (tmp_path / "links").mkdir()
    real = tmp_path / "real" / "tool.json"
    real.write_text("old")
    real.chmod(0o4755)
    link = tmp_path / "links" / "tool.json"
    link.symlink_to(real)
    assert check_output_file(link, "profile", inputs=()) == link
    write_bytes_atomic(link, b"new")
    assert link.is_symlink() and os.readlink(link) == str(real)  # the link stays, its target is replaced
    assert real.read_bytes() == b"new" and real.stat().st_mode & 0o7777 == 0o755
    assert sorted(p.name for p in (tmp_path / "real").iterdir()) == ["tool.json"]
    assert sorted(p.name for p in (tmp_path / "links").iterdir()) == ["tool.json"]


def test_outputs_get_the_umask_mode_or_the_replaced_files_mode(tmp_path):
    import os

    import numpy as np

    from lenticalib.core.files.atomic import write_bytes_atomic
    from lenticalib.render.pipeline.offline import _VideoFile

    old_mask = os.umask(0o027)
    try:
        write_bytes_atomic(tmp_path / "new.json", b"{}")
        (tmp_path / "shared.json").write_text("{}")
        (tmp_path / "shared.json").chmod(0o644)
        write_bytes_atomic(tmp_path / "shared.json", b"{ }")
        raster = np.zeros((32, 64, 3), np.uint8)
        for name, mode in (("new.mkv", None), ("shared.mkv", 0o644)):
            if mode is not None:
                (tmp_path / name).write_bytes(b"an earlier video")
                (tmp_path / name).chmod(mode)
            video = _VideoFile(str(tmp_path / name), 30.0)
            video.write(raster)
            video.finish()
    finally:
        os.umask(old_mask)
    modes = {p.name: p.stat().st_mode & 0o7777 for p in tmp_path.iterdir()}
    assert modes == {"new.json": 0o640, "shared.json": 0o644, "new.mkv": 0o640, "shared.mkv": 0o644}


def test_a_folder_that_takes_no_files_is_named_not_writable(tmp_path):
    """/proc exists and passes os.access for root, but no file can be made there."""
    from lenticalib.core.files.atomic import write_bytes_atomic

    for call in (lambda: check_output_file("/proc/lenticalib-test.json", "profile", inputs=()),
                 lambda: write_bytes_atomic("/proc/lenticalib-test.json", b"{}")):
        with pytest.raises(InputError) as info:
            call()
        assert str(info.value).startswith("/proc: folder is not writable"), str(info.value)


# ---------------------------------------------------------------------------------------------
# folders: foreign files at any depth, links, and what killed runs left behind
# ---------------------------------------------------------------------------------------------

def test_staged_folder_refuses_foreign_files_at_any_depth_and_follows_a_link(tmp_path):
    contents = ("cameras.json", "frame-[0-9]*", "frame-[0-9]*/view-[0-9]*.png")
    views = tmp_path / "views"
    (views / "frame-00000").mkdir(parents=True)
    (views / "frame-00000" / "view-00.png").write_bytes(b"png")
    (views / "frame-00000" / "thesis.tex").write_text("my work")
    before = _tree(tmp_path)
    with pytest.raises(InputError) as info:
        with staged_folder(views, "views folder", contents, inputs=()):
            pytest.fail("the work started")
    assert str(info.value).startswith(f"{views}: holds 'frame-00000/thesis.tex'"), str(info.value)
    assert _tree(tmp_path) == before

    (views / "frame-00000" / "thesis.tex").unlink()
    link = tmp_path / "link"
    link.symlink_to(views)
    with pytest.raises(InputError, match="holds 'late.txt'"):  # checked again when the folder is replaced
        with staged_folder(link, "views folder", contents, inputs=()) as stage:
            (stage / "cameras.json").write_text("{}")
            (tmp_path / "views" / "late.txt").write_text("put there while the work ran")
    assert link.is_symlink() and _tree(views) == {"frame-00000": None, "frame-00000/view-00.png": b"png",
                                                  "late.txt": b"put there while the work ran"}
    (views / "late.txt").unlink()
    with staged_folder(link, "views folder", contents, inputs=()) as stage:
        (stage / "cameras.json").write_text("{}")
    assert link.is_symlink() and _tree(views) == {"cameras.json": b"{}"}
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_restored_on_failure_never_copies_or_replaces_a_node(tmp_path):
    nodes = _nodes(tmp_path / "nodes")
    nodes.pop("folder")  # a folder is a result like any other
    nodes.pop("dangling link")  # nothing to copy or replace: written through, never replaced
    before = {name: _identity(path) for name, path in nodes.items()}
    for name, path in nodes.items():
        with pytest.raises(InputError):
            with restored_on_failure([path]):
                pytest.fail("the work started")
    assert {name: _identity(path) for name, path in nodes.items()} == before


_KILLED_WRITER = """
import sys, time
from lenticalib.core.files.atomic import PendingFile
from lenticalib.core.files.outputs import staged_folder
with staged_folder(sys.argv[1], "frames folder", ("frame-*.png",), inputs=()) as stage:
    (stage / "frame-00000.png").write_bytes(b"half")
    video = PendingFile(sys.argv[2], "video", suffix=".mkv")
    video.write(b"half a video")
    print("writing", flush=True)
    time.sleep(60)
"""


def test_what_a_killed_run_left_is_removed_by_the_next_run_of_the_same_output(tmp_path):
    import os
    import signal
    import subprocess
    import sys

    from lenticalib.core.files.atomic import remove_leftovers, write_bytes_atomic

    frames, video = tmp_path / "frames", tmp_path / "out.mkv"
    decoys = {".frames.notes": b"mine", ".frames.abcd1234.partial.txt": b"mine", ".other.abcd1234.tmp": b"mine",
              "frames.abcd1234.tmp": b"mine", ".out.mkv.abcd1234.keep": b"mine"}
    for name, data in decoys.items():
        (tmp_path / name).write_bytes(data)
    (tmp_path / ".frames.abcd1234.old").mkdir()  # an earlier result kept by a killed swap: never removed
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parent.parent)}
    proc = subprocess.Popen([sys.executable, "-c", _KILLED_WRITER, str(frames), str(video)], stdout=subprocess.PIPE,
                            text=True, env=env)
    try:
        assert proc.stdout.readline().strip() == "writing"
        running = sorted(p.name for p in tmp_path.iterdir() if p.name not in decoys)
        assert remove_leftovers(frames) == [] and remove_leftovers(video) == []  # in use: kept
        assert sorted(p.name for p in tmp_path.iterdir() if p.name not in decoys) == running
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    left = [p.name for p in tmp_path.iterdir() if p.name not in decoys and p.name != ".frames.abcd1234.old"]
    assert len(left) == 2 and any(n.endswith(".partial") for n in left) and any(n.endswith(".tmp.mkv") for n in left)

    with staged_folder(frames, "frames folder", ("frame-*.png",), inputs=()) as stage:
        (stage / "frame-00000.png").write_bytes(b"whole")
    write_bytes_atomic(video, b"a whole video")
    assert _tree(tmp_path) == {**decoys, ".frames.abcd1234.old": None, "frames": None,
                               "frames/frame-00000.png": b"whole", "out.mkv": b"a whole video"}


def test_a_failed_swap_puts_the_earlier_folder_back(tmp_path, monkeypatch):
    import errno
    import os

    target = tmp_path / "report"
    with staged_folder(target, "report", ("a.txt",), inputs=()) as stage:
        (stage / "a.txt").write_text("first")
    real_replace = os.replace

    def replace(source, destination):
        if str(source).endswith(".partial"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_replace(source, destination)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(InputError, match="No space left"):
        with staged_folder(target, "report", ("a.txt",), inputs=()) as stage:
            (stage / "a.txt").write_text("second")
    assert _tree(tmp_path) == {"report": None, "report/a.txt": b"first"}


def test_a_file_of_our_own_folder_replaces_a_planted_link_instead_of_writing_through_it(tmp_path):
    """write_text_atomic(..., follow_links=False) (the emulator's announcements): the link at the name
    is replaced by the new file and what it pointed to is never written."""
    from lenticalib.core.files.atomic import write_text_atomic

    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    link = tmp_path / "1.json"
    link.symlink_to(victim)
    write_text_atomic(link, '{"url": "emu://x"}', follow_links=False)
    assert not link.is_symlink() and link.read_text() == '{"url": "emu://x"}'
    assert victim.read_text() == "keep me"
