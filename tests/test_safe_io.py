"""Files written never through a link nor outside the folder named; files read only if regular and bounded.

The symlink attacks plant a link at every name a command writes, pointing at a
victim file in another folder, and check that the command refuses with one
line (exit 2) and that the victim is untouched.
"""

import os
import stat

import numpy as np
import pytest

from hammerstein_ctrl import load_trs
from hammerstein_ctrl.cli._main import REPRODUCE_OUTPUTS, main
from hammerstein_ctrl.exceptions import DataError, DataNotFoundError
from hammerstein_ctrl._safe_io import (MAX_BYTES_ENV, UnsafePathError, check_input, open_append, open_lock, read_bytes,
                                       save_figure, write_bytes, write_text)

VICTIM_TEXT = "precious data\n"


@pytest.fixture
def victim(tmp_path):
    folder = tmp_path / "elsewhere"
    folder.mkdir()
    path = folder / "victim.txt"
    path.write_text(VICTIM_TEXT)
    os.utime(path, (1_000_000_000, 1_000_000_000))
    return path


def untouched(victim) -> bool:
    return victim.read_text() == VICTIM_TEXT and victim.stat().st_mtime == 1_000_000_000


def one_error_line(capsys, code) -> str:
    out, err = capsys.readouterr()
    rows = [r for r in err.splitlines() if r.strip()]
    assert code == 2 and len(rows) == 1 and rows[0].startswith("hammerstein-ctrl: error: "), (code, err)
    assert "unexpected failure" not in rows[0] and "Traceback" not in err
    return rows[0]


# -- the primitives --------------------------------------------------------------------------------------
def test_write_replaces_the_file_whole_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "a.txt"
    write_text(target, "one")
    write_bytes(target, b"two")
    assert target.read_bytes() == b"two" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


@pytest.mark.parametrize("writer", ["write_text", "write_bytes", "save_figure", "open_append", "open_lock"])
@pytest.mark.parametrize("dangling", [False, True], ids=["link", "dangling-link"])
def test_every_writer_refuses_a_symbolic_link(tmp_path, victim, writer, dangling):
    link = tmp_path / "out.png"
    os.symlink(tmp_path / "nowhere" if dangling else victim, link)
    with pytest.raises(UnsafePathError, match="symbolic link"):
        if writer == "write_text":
            write_text(link, "x")
        elif writer == "write_bytes":
            write_bytes(link, b"x")
        elif writer == "save_figure":
            import matplotlib.figure

            save_figure(matplotlib.figure.Figure(), link)
        elif writer == "open_append":
            open_append(link)
        else:
            open_lock(link)
    assert untouched(victim) and not (tmp_path / "nowhere").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["elsewhere", "out.png"]      # no temporary left


def test_a_link_race_after_the_check_still_cannot_redirect_a_lock(tmp_path, victim, monkeypatch):
    """The check is a courtesy; O_NOFOLLOW is the guarantee: a link planted between the two is refused."""
    import hammerstein_ctrl._safe_io as safe_io

    lock = tmp_path / "r.lock"

    def racing_check(path, *, root=None):
        os.symlink(victim, lock)
        return lock

    monkeypatch.setattr(safe_io, "check_output", racing_check)
    with pytest.raises(UnsafePathError, match="symbolic link"):
        safe_io.open_lock(lock)
    assert untouched(victim)


def test_a_write_outside_the_root_is_refused(tmp_path, victim):
    out = tmp_path / "out"
    out.mkdir()
    with pytest.raises(UnsafePathError, match="outside"):
        write_text(out / ".." / "elsewhere" / "new.txt", "x", root=out)
    assert not (victim.parent / "new.txt").exists()


def test_a_folder_is_not_a_file_to_write(tmp_path):
    with pytest.raises(UnsafePathError, match="is a folder: give a file name"):
        write_text(tmp_path, "x")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_reads_refuse_fifos_devices_and_folders_at_once(tmp_path):
    fifo = tmp_path / "m.json"
    os.mkfifo(fifo)                 # opening it for reading would block forever
    with pytest.raises(DataError, match="is a FIFO, not a regular file"):
        read_bytes(fifo, limit=100)
    zero = tmp_path / "zero.json"
    os.symlink("/dev/zero", zero)   # reading it would never end
    with pytest.raises(DataError, match="is a device, not a regular file"):
        read_bytes(zero, limit=100)
    with pytest.raises(DataError, match="is a folder"):
        read_bytes(tmp_path, limit=100)
    with pytest.raises(DataNotFoundError, match="not found"):
        read_bytes(tmp_path / "missing.json", limit=100)


def test_the_size_limit_names_the_size_and_how_to_raise_it(tmp_path, monkeypatch):
    path = tmp_path / "big.json"
    with open(path, "wb") as fh:
        fh.truncate(3_000_000)      # sparse: no disk used
    with pytest.raises(DataError, match=rf"3.0 MB, larger than the limit of 1.0 MB .*{MAX_BYTES_ENV}=<bytes>"):
        check_input(path, limit=1_000_000, what="model file")
    monkeypatch.setenv(MAX_BYTES_ENV, "4000000")
    assert check_input(path, limit=1_000_000) == 3_000_000
    monkeypatch.setenv(MAX_BYTES_ENV, "-1")
    with pytest.raises(DataError, match="positive number of bytes"):
        check_input(path, limit=1_000_000)


# -- every output of the command line -----------------------------------------------------------------------
@pytest.fixture
def trs_csv(tmp_path):
    return load_trs()[:1000].to_csv(tmp_path / "trs.csv")


REPRODUCE = ["reproduce", "trs", "--methods", "nspsa", "--trials", "1", "--jobs", "1", "--no-progress"]


@pytest.mark.parametrize("name", [*REPRODUCE_OUTPUTS, "figures", "figures/time_response.png"])
def test_reproduce_refuses_a_link_at_any_output_before_working(capsys, tmp_path, victim, name):
    out = tmp_path / "out"
    (out / "figures").mkdir(parents=True)
    target = out / name
    if name == "figures":
        (out / "figures").rmdir()
        os.symlink(victim.parent, target)
    else:
        os.symlink(victim, target)
    code = main([*REPRODUCE, "--out", str(out)])
    if name.startswith("figures/"):          # seen only when the figures are written, after the study
        out_err = capsys.readouterr()
        assert code == 2 and "symbolic link" in out_err.err
    else:
        assert "symbolic link" in one_error_line(capsys, code)
        assert not (out / "results.jsonl").is_file() or name == "results.jsonl"
    assert untouched(victim) and sorted(p.name for p in victim.parent.iterdir()) == ["victim.txt"]


def test_reproduce_repairs_a_damaged_results_file_without_a_fixed_temporary_name(capsys, tmp_path, victim):
    out = tmp_path / "out"
    code = main([*REPRODUCE, "--no-figures", "--out", str(out)])
    assert code == 0
    capsys.readouterr()
    with open(out / "results.jsonl", "a") as fh:
        fh.write('{"damaged": \n')
    os.symlink(victim, out / "results.jsonl.tmp")       # the name an earlier version wrote through
    code = main([*REPRODUCE, "--no-figures", "--trials", "2", "--out", str(out)])
    assert code == 0 and "1 line(s) rejected" in capsys.readouterr().err and untouched(victim)
    assert not (out / "results.jsonl").is_symlink() and len((out / "results.jsonl").read_text().splitlines()) == 2


def test_identify_refuses_links_at_out_and_plot(capsys, tmp_path, victim, trs_csv):
    for option in ("--out", "--plot"):
        link = tmp_path / f"link{option[2:]}"
        os.symlink(victim, link)
        code = main(["identify", "--data", str(trs_csv), "--structure", "trs", "--method", "lm", "--maxfev", "50",
                     option, str(link)])
        assert "symbolic link" in one_error_line(capsys, code)
    assert untouched(victim)


def test_saving_a_model_or_result_never_follows_a_link(tmp_path, victim):
    import control

    from hammerstein_ctrl import Coulomb, HammersteinModel
    from hammerstein_ctrl.io import save_model

    link = tmp_path / "m.json"
    os.symlink(victim, link)
    with pytest.raises(UnsafePathError, match="symbolic link"):
        save_model(HammersteinModel(control.tf([1], [1, 3, 0]), Coulomb(), [0.5, -0.4, 0.05]), link)
    assert untouched(victim)


@pytest.fixture
def model_json(tmp_path):
    import control

    from hammerstein_ctrl import Coulomb, HammersteinModel
    from hammerstein_ctrl.io import save_model

    path = tmp_path / "m.json"
    save_model(HammersteinModel(control.tf([1], [1, 3.1, 0]), Coulomb(), [0.5, -0.4, 0.05]), path)
    return path


def test_tune_refuses_a_link_at_its_figure(capsys, tmp_path, victim, model_json):
    link = tmp_path / "pid.png"
    os.symlink(victim, link)
    code = main(["tune", str(model_json), "--plot", str(link)])
    assert "symbolic link" in one_error_line(capsys, code)
    assert untouched(victim)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
@pytest.mark.parametrize("kind", ["fifo", "dev-zero", "folder", "missing"])
def test_tune_reads_only_a_regular_model_file(capsys, tmp_path, kind):
    path = tmp_path / "m.json"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev-zero":
        os.symlink("/dev/zero", path)
    elif kind == "folder":
        path.mkdir()
    line = one_error_line(capsys, main(["tune", str(path)]))
    assert {"fifo": "is a FIFO", "dev-zero": "is a device", "folder": "is a folder",
            "missing": "not found"}[kind] in line


def test_select_refuses_links_at_table_and_out(capsys, tmp_path, victim, trs_csv):
    for option in ("--table", "--out"):
        link = tmp_path / f"link{option[2:]}"
        os.symlink(victim, link)
        code = main(["select", "--data", str(trs_csv), "--orders", "0", "1", "--nonlinearity", "tanh", option,
                     str(link)])
        assert "symbolic link" in one_error_line(capsys, code)
    assert untouched(victim)


def test_files_written_are_regular_and_private_to_the_folder(tmp_path):
    write_text(tmp_path / "a.txt", "x")
    mode = (tmp_path / "a.txt").stat().st_mode
    assert stat.S_ISREG(mode) and np.all([not p.is_symlink() for p in tmp_path.iterdir()])


@pytest.mark.skipif(not hasattr(os, "fchmod"), reason="POSIX permissions")
@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002])
def test_written_files_get_the_permissions_a_plain_open_gives(tmp_path, mask):
    old = os.umask(mask)
    try:
        write_text(tmp_path / "new.txt", "x")
        with open(tmp_path / "plain.txt", "w") as fh:
            fh.write("x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "new.txt").stat().st_mode) == stat.S_IMODE((tmp_path / "plain.txt").stat().st_mode)


@pytest.mark.skipif(not hasattr(os, "fchmod"), reason="POSIX permissions")
def test_a_replaced_file_keeps_its_permissions(tmp_path):
    (tmp_path / "a.txt").write_text("old")
    os.chmod(tmp_path / "a.txt", 0o640)
    write_text(tmp_path / "a.txt", "new")
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o640 and (tmp_path / "a.txt").read_text() == "new"
