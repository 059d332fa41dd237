"""Writing never destroys (issue 11, part 1): every output target of every verb, as a hostile user picks it.

Each refusal ends with exit code 2 and one line on stderr naming the option and the path,
and nothing at or around the target is created or changed: a snapshot of the test's
folder (kind, inode, mtime, content or link text of every entry) is equal before and after.
FIFOs, sockets, symlinks, folders and (where the test may create one) a device node are
made in ``tmp_path``; no real system path is touched. Write errors come from a real
read-only or full tmpfs where the test may mount one (root), from ``chmod`` otherwise, and
from injected ``ENOSPC``/``EACCES`` everywhere.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import socket
import stat
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from folder_line.cli.main import main
from folder_line.cli.report import REPORT_FILES
from folder_line.files.atomic import claim_output_dir

REPO = Path(__file__).resolve().parents[2]
ROOT = os.geteuid() == 0

Snapshot = dict[str, tuple[Any, ...]]


def snapshot(root: Path, folder_mtimes: bool = True) -> Snapshot:
    """Kind, inode, mtime and content (regular files) or link text (symlinks) of everything under ``root``.

    ``folder_mtimes=False`` leaves out the folders' mtimes, which a temporary file created and
    removed again (a write that failed) changes.
    """
    out: Snapshot = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in (*dirnames, *filenames):
            p = Path(dirpath) / name
            st = os.lstat(p)
            extra: Any = None
            if stat.S_ISLNK(st.st_mode):
                extra = os.readlink(p)
            elif stat.S_ISREG(st.st_mode):
                extra = p.read_bytes()
            mtime = st.st_mtime_ns if folder_mtimes or not stat.S_ISDIR(st.st_mode) else None
            out[str(p.relative_to(root))] = (stat.S_IFMT(st.st_mode), st.st_ino, mtime, extra)
    st = os.lstat(root)
    out['.'] = (stat.S_IFMT(st.st_mode), st.st_ino, st.st_mtime_ns if folder_mtimes else None, None)
    return out


def refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run the command; assert exit code 2 and one error line without a traceback; return the line."""
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count('\n') == 1 and err.startswith('folder-line: error: '), err
    assert 'Traceback' not in err
    return err.rstrip('\n')


# --------------------------------------------------------------------------- hostile targets


def _fifo(p: Path) -> None:
    os.mkfifo(p)


def _dir(p: Path) -> None:
    p.mkdir()


def _file(p: Path) -> None:
    p.write_text('precious\n')


@contextlib.contextmanager
def _cwd(path: Path) -> Iterator[None]:
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


_SOCKETS: list[socket.socket] = []


def _socket(p: Path) -> None:
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    with _cwd(p.parent):  # relative name: tmp_path may be longer than sun_path allows
        s.bind(p.name)
    _SOCKETS.append(s)


def _device(p: Path) -> None:
    try:  # a character device node with /dev/null's numbers, made in tmp_path
        os.mknod(p, stat.S_IFCHR | 0o600, os.makedev(1, 3))
    except OSError as exc:
        pytest.skip(f'cannot make a device node here ({exc.strerror}): needs CAP_MKNOD')


def _link_to(make: Callable[[Path], None]) -> Callable[[Path], None]:
    def build(p: Path) -> None:
        target = p.with_name(p.name + '.target')
        make(target)
        p.symlink_to(target.name)

    return build


def _dangling(p: Path) -> None:
    p.symlink_to('nowhere')


def _under_a_file(p: Path) -> None:
    _file(p)  # the target is p/'x': under a regular file


#: what stands where a file is to be written, and the words of the refusal
FILE_TARGETS: dict[str, tuple[Callable[[Path], None], str]] = {
    'fifo': (_fifo, 'is a FIFO, not a regular file'),
    'directory': (_dir, 'is a directory, not a regular file'),
    'socket': (_socket, 'is a socket, not a regular file'),
    'device': (_device, 'is a character device, not a regular file'),
    'link to a fifo': (_link_to(_fifo), 'is a symbolic link to a FIFO'),
    'link to a directory': (_link_to(_dir), 'is a symbolic link to a directory'),
    'dangling link': (_dangling, 'dangling'),
    'under a file': (_under_a_file, 'is a regular file, not a directory'),
}

#: what stands where a folder is to be written
DIR_TARGETS: dict[str, tuple[Callable[[Path], None], str]] = {
    'regular file': (_file, 'is a regular file, not a directory'),
    'fifo': (_fifo, 'is a FIFO, not a directory'),
    'socket': (_socket, 'is a socket, not a directory'),
    'device': (_device, 'is a character device, not a directory'),
    'link to a fifo': (_link_to(_fifo), 'is a FIFO, not a directory'),
    'dangling link': (_dangling, 'dangling'),
    'under a file': (_under_a_file, 'is a regular file, not a directory'),
}

FILE_VERBS = {
    'kinematics --csv': ['kinematics', 'knife', '--samples', '8', '--csv'],
    'simulate --json': ['simulate', '--duration', '0.05', '--json'],
}


def _empty_bag(run_dir: Path) -> Path:
    """A bag with the folder scene and no messages (what ``analyze`` needs to reach its output)."""
    from folder_line.bag.writer import BagWriter
    from folder_line.config.scenes import scene_mapping
    from folder_line.ros.recorder import LINE_TOPICS

    source = yaml.safe_dump(scene_mapping('folder'), sort_keys=False)
    with BagWriter(run_dir / 'bag', scene_source=source, effects=[], scene_name='folder', topics=LINE_TOPICS):
        pass
    return run_dir


def _folder_argv(verb: str, run_dir: Path, target: Path) -> list[str]:
    return {
        'run': ['run', '--duration', '1', '--out', str(target)],
        'report': ['report', '--out', str(target)],
        'analyze': ['analyze', str(run_dir), '--out', str(target), '--csv'],
        'bench': ['bench', 'accuracy', '--quick', '--out', str(target)],
    }[verb]


FOLDER_VERBS = ('run', 'report', 'analyze', 'bench')


@pytest.fixture(scope='module')
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _empty_bag(tmp_path_factory.mktemp('recorded'))


@pytest.fixture(autouse=True)
def _close_sockets() -> Iterator[None]:
    yield
    while _SOCKETS:
        _SOCKETS.pop().close()


@pytest.mark.parametrize('kind', list(FILE_TARGETS))
@pytest.mark.parametrize('verb', list(FILE_VERBS))
def test_file_target_that_is_not_a_regular_file_is_refused_untouched(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], verb: str, kind: str
) -> None:
    make, why = FILE_TARGETS[kind]
    place = tmp_path / 'place'
    place.mkdir()
    make(place / 't')
    target = place / 't' / 'x' if kind == 'under a file' else place / 't'
    before = snapshot(tmp_path)
    line = refused([*FILE_VERBS[verb], str(target)], capsys)
    assert f"{verb.split()[1]}='{target}'" in line and why in line, line
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize('kind', list(DIR_TARGETS))
@pytest.mark.parametrize('verb', FOLDER_VERBS)
def test_folder_target_that_is_not_a_folder_is_refused_untouched(
    tmp_path: Path, run_dir: Path, capsys: pytest.CaptureFixture[str], verb: str, kind: str
) -> None:
    make, why = DIR_TARGETS[kind]
    place = tmp_path / 'place'
    place.mkdir()
    make(place / 't')
    target = place / 't' / 'x' if kind == 'under a file' else place / 't'
    before = snapshot(tmp_path)
    line = refused(_folder_argv(verb, run_dir, target), capsys)
    assert f"--out='{target}'" in line and why in line, line
    assert snapshot(tmp_path) == before


#: an entry inside the output folder that the verb must not replace
INNER = {
    'run': ('run.json', _fifo, 'is a FIFO'),
    'report': (REPORT_FILES[3], _dir, 'is a directory'),
    'analyze': ('csv', _file, 'is a regular file, not a directory'),
    'bench': ('accuracy.json', _link_to(_fifo), 'is a symbolic link to a FIFO'),
}


@pytest.mark.parametrize('verb', FOLDER_VERBS)
def test_what_a_verb_would_overwrite_inside_its_folder_is_checked_first(
    tmp_path: Path, run_dir: Path, capsys: pytest.CaptureFixture[str], verb: str
) -> None:
    name, make, why = INNER[verb]
    out = tmp_path / 'out'
    out.mkdir()
    (out / 'keep.txt').write_text('mine\n')
    make(out / name)
    before = snapshot(tmp_path)
    line = refused(_folder_argv(verb, run_dir, out), capsys)
    assert f"--out='{out / name}'" in line and why in line, line
    assert snapshot(tmp_path) == before


def test_the_merged_scene_a_run_writes_is_checked_first(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'out'
    out.mkdir()
    _dir(out / 'scene.yaml')  # run writes the merged scene there for its nodes
    before = snapshot(tmp_path)
    line = refused(['run', '--duration', '1', '--out', str(out)], capsys)
    assert f"--out='{out / 'scene.yaml'}'" in line and 'is a directory' in line, line
    assert snapshot(tmp_path) == before


def test_symlink_to_a_regular_file_is_followed_and_stays_a_link(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    real = tmp_path / 'data' / 'table.csv'
    real.parent.mkdir()
    real.write_text('old\n')
    link = tmp_path / 'link.csv'
    link.symlink_to(Path('data') / 'table.csv')
    assert main(['kinematics', 'knife', '--samples', '8', '--csv', str(link)]) == 0
    assert f'wrote {link}' in capsys.readouterr().out
    assert link.is_symlink() and os.readlink(link) == str(Path('data') / 'table.csv')
    assert real.read_text().startswith('phi,s,v,a,in_window\n')
    assert sorted(p.name for p in tmp_path.rglob('*')) == ['data', 'link.csv', 'table.csv']  # no temp file


def test_a_symlinked_output_folder_is_followed(
    tmp_path: Path, run_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / 'real').mkdir()
    (tmp_path / 'out').symlink_to('real')
    assert main(['analyze', str(run_dir), '--out', str(tmp_path / 'out')]) == 0
    assert (tmp_path / 'out').is_symlink() and (tmp_path / 'real' / 'report.md').is_file()


@pytest.mark.parametrize('kind', [k for k in DIR_TARGETS if k != 'under a file'])
def test_bag_repair_of_something_that_is_not_a_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    make, why = DIR_TARGETS[kind]
    make(tmp_path / 'bag')
    before = snapshot(tmp_path)
    line = refused(['bag', 'repair', str(tmp_path / 'bag')], capsys)
    assert f"DIR='{tmp_path / 'bag'}'" in line and why in line, line
    assert snapshot(tmp_path) == before


def test_bag_repair_leaves_a_metadata_fifo_and_a_missing_folder_alone(
    tmp_path: Path, run_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'bag_0.mcap').write_bytes((run_dir / 'bag' / 'bag_0.mcap').read_bytes())
    os.mkfifo(bag / 'metadata.yaml')
    before = snapshot(tmp_path)
    line = refused(['bag', 'repair', str(bag)], capsys)
    assert line == f"folder-line: error: DIR='{bag / 'metadata.yaml'}': is a FIFO, not a regular file"
    line = refused(['bag', 'repair', str(tmp_path / 'missing')], capsys)
    assert line == f"folder-line: error: DIR='{tmp_path / 'missing'}': no such directory"
    assert snapshot(tmp_path) == before


# --------------------------------------------------------------------------- folders are claimed


@pytest.mark.parametrize('verb', FOLDER_VERBS)
def test_a_folder_in_use_is_refused_and_keeps_what_it_holds(
    tmp_path: Path, run_dir: Path, capsys: pytest.CaptureFixture[str], verb: str
) -> None:
    out = tmp_path / 'out'
    (out / 'bag').mkdir(parents=True)  # the first run's bag: the second run deleted it
    (out / 'bag' / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    (out / 'bag' / 'bag_0.mcap').write_bytes(b'\x89MCAP0\r\n')
    with claim_output_dir(out, '--out'):
        before = snapshot(tmp_path)
        line = refused(_folder_argv(verb, run_dir, out), capsys)
    assert line == (
        f"folder-line: error: --out='{out}': is in use by another folder-line process; "
        'wait for it to finish or choose another folder'
    )
    assert snapshot(tmp_path) == before


def test_bag_repair_is_refused_while_the_run_folder_is_in_use(
    tmp_path: Path, run_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / 'out'
    (out / 'bag').mkdir(parents=True)
    (out / 'bag' / 'bag_0.mcap').write_bytes((run_dir / 'bag' / 'bag_0.mcap').read_bytes())
    with claim_output_dir(out, '--out'):  # a run writing out/bag
        before = snapshot(tmp_path)
        line = refused(['bag', 'repair', str(out / 'bag')], capsys)
        assert snapshot(tmp_path) == before
    assert line == (
        f"folder-line: error: DIR='{out}': is in use by another folder-line process; "
        'wait for it to finish or choose another folder'
    )
    assert main(['bag', 'repair', str(out / 'bag')]) == 0  # released: repair does its work
    assert (out / 'bag' / 'metadata.yaml').is_file()


def test_another_process_is_refused_while_a_folder_is_claimed(tmp_path: Path) -> None:
    out = tmp_path / 'out'
    command = [sys.executable, '-m', 'folder_line.cli.main', 'report', '--out', str(out)]
    env = {**os.environ, 'PYTHONPATH': str(REPO)}
    with claim_output_dir(out, '--out') as claimed:
        assert claimed == out and out.is_dir()
        proc = subprocess.run(command, capture_output=True, text=True, timeout=120, env=env, check=False)
        assert proc.returncode == 2 and proc.stdout == ''
        assert (
            proc.stderr == f"folder-line: error: --out='{out}': is in use by another folder-line process; "
            'wait for it to finish or choose another folder\n'
        )
        assert list(out.iterdir()) == []
    proc = subprocess.run(command, capture_output=True, text=True, timeout=120, env=env, check=False)
    assert proc.returncode == 0, proc.stderr  # released: the folder is usable again
    assert sorted(p.name for p in out.iterdir()) == sorted(REPORT_FILES)


def test_a_claim_removes_the_folders_it_created_when_nothing_was_written(tmp_path: Path) -> None:
    out = tmp_path / 'a' / 'b' / 'c'
    with pytest.raises(RuntimeError), claim_output_dir(out, '--out'):
        assert out.is_dir()
        raise RuntimeError('the verb failed before writing')
    assert list(tmp_path.iterdir()) == []
    with claim_output_dir(out, '--out'):
        (out / 'result.txt').write_text('1\n')
    assert (out / 'result.txt').read_text() == '1\n'  # a folder with output stays


def test_run_with_a_bad_scene_creates_no_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    refused(['run', '--scene', str(tmp_path / 'missing.yaml'), '--out', str(tmp_path / 'out')], capsys)
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- write errors


class _FullDisk(io.FileIO):
    """A file on a full disk: every write fails as the kernel's would."""

    def write(self, data: Any) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _file_argv(verb: str, target: Path) -> list[str]:
    return [*FILE_VERBS[verb], str(target)]


@pytest.mark.parametrize('verb', [*FILE_VERBS, 'report', 'analyze'])
def test_disk_full_is_one_line_and_leaves_nothing(
    tmp_path: Path, run_dir: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], verb: str
) -> None:
    old = tmp_path / 'old.out'
    old.write_text('previous result\n')
    monkeypatch.setattr(os, 'fdopen', lambda fd, mode='r', *a, **k: _FullDisk(fd, 'w'))
    before = snapshot(tmp_path, folder_mtimes=False)
    for target in (old, tmp_path / 'new' / 'sub' / 'x.out'):
        if verb in FILE_VERBS:
            line = refused(_file_argv(verb, target), capsys)
            assert line == f"folder-line: error: {verb.split()[1]}='{target}': cannot write: No space left on device"
        elif target != old:  # a folder verb: into a folder it creates
            line = refused(_folder_argv(verb, run_dir, target.parent), capsys)
            assert line.startswith(f"folder-line: error: --out='{target.parent}/"), line
            assert line.endswith("': cannot write: No space left on device"), line
        assert snapshot(tmp_path, folder_mtimes=False) == before  # the old file as it was, no temp file or folder


@pytest.fixture
def small_tmpfs(tmp_path: Path) -> Iterator[Callable[[str], Path]]:
    """``mount(options)``: a fresh tmpfs under ``tmp_path`` (needs root; skipped otherwise)."""
    mounted: list[Path] = []

    def mount(options: str) -> Path:
        point = tmp_path / f'mnt{len(mounted)}'
        point.mkdir()
        proc = (
            subprocess.run(
                ['mount', '-t', 'tmpfs', '-o', options, 'tmpfs', str(point)],
                capture_output=True,
                text=True,
                check=False,
            )
            if ROOT
            else None
        )
        if proc is None or proc.returncode != 0:
            pytest.skip(
                'mounting a tmpfs needs root with CAP_SYS_ADMIN: ' + (proc.stderr.strip() if proc else 'not root')
            )
        mounted.append(point)
        return point

    yield mount
    for point in mounted:
        subprocess.run(['umount', '-l', str(point)], check=False)


def test_real_full_disk(small_tmpfs: Callable[[str], Path], capsys: pytest.CaptureFixture[str]) -> None:
    disk = small_tmpfs('size=64k')
    (disk / 'kept.csv').write_text('x\n1\n')
    before = snapshot(disk, folder_mtimes=False)
    line = refused(['kinematics', 'layup', '--samples', '20000', '--csv', str(disk / 'kept.csv')], capsys)
    assert line == f"folder-line: error: --csv='{disk / 'kept.csv'}': cannot write: No space left on device"
    assert snapshot(disk, folder_mtimes=False) == before


def test_a_video_on_a_full_disk_keeps_the_one_there(
    small_tmpfs: Callable[[str], Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """ffmpeg fails on the full disk and says so only in its log: the video it leaves is checked, refused, and
    the old file stays (issue 25: it was replaced by a 0-byte file, with ``wrote`` and exit 0)."""
    disk = small_tmpfs('size=256k')
    (disk / 'x.mp4').write_bytes(b'the previous video')
    with contextlib.suppress(OSError), open(disk / 'fill', 'wb') as f:
        f.write(bytes(1 << 20))  # fills the disk: ENOSPC part way
    before = snapshot(disk, folder_mtimes=False)
    argv = ['animate', '--scene', 'folder', '--duration', '2', '--fps', '1', '--slowdown', '1']
    assert main([*argv, '--out', str(disk / 'x.mp4')]) == 2
    err = capsys.readouterr().err  # the progress lines of the drawing, then the error
    assert 'Traceback' not in err and "wrote '" not in err and 'wrote ' + str(disk) not in err
    (line,) = [x for x in err.splitlines() if x.startswith('folder-line')]
    assert line.startswith(f"folder-line: error: --out='{disk / 'x.mp4'}': cannot write: ffmpeg: wrote no readable")
    assert snapshot(disk, folder_mtimes=False) == before


@pytest.mark.parametrize('existing', [False, True])
def test_a_bag_on_a_full_disk_leaves_nothing_and_names_the_bag(
    small_tmpfs: Callable[[str], Path], capsys: pytest.CaptureFixture[str], existing: bool
) -> None:
    """The disk fills part way through ``simulate --bag``: one line naming ``--bag`` and its path (it named
    ``--json`` and no path), and the folder is as it was: gone if it was made for the bag, empty if it was."""
    disk = small_tmpfs('size=300k')
    bag = disk / 'bag'
    if existing:
        bag.mkdir()
    before = snapshot(disk, folder_mtimes=False)
    assert main(['simulate', '--scene', 'folder', '--duration', '20', '--bag', str(bag)]) == 2
    err = capsys.readouterr().err
    assert 'Traceback' not in err
    (line,) = [x for x in err.splitlines() if x.startswith('folder-line')]
    assert line == f"folder-line: error: --bag='{bag}': cannot write: No space left on device"
    assert snapshot(disk, folder_mtimes=False) == before


@pytest.mark.parametrize(
    ('argv', 'option', 'name'),
    [
        (['simulate', '--scene', 'folder', '--duration', '2', '--plots'], '--plots', 'efficiency.png'),
        (
            [
                'sweep',
                '--vary',
                'feed_transporter.V_tr=9:10:2',
                '--scene',
                'folder',
                '--duration',
                '1',
                '--workers',
                '1',
                '--out',
            ],
            '--out',
            'sweep.png',
        ),
    ],
    ids=['plots', 'sweep'],
)
def test_figures_on_a_full_disk_leave_nothing_and_name_their_option(
    small_tmpfs: Callable[[str], Path], capsys: pytest.CaptureFixture[str], argv: list[str], option: str, name: str
) -> None:
    """The disk fills after the first files: those go too, and the error names the option of the folder (the
    figures named ``--json``; a sweep left its CSV behind)."""
    disk = small_tmpfs('size=100k')
    before = snapshot(disk, folder_mtimes=False)
    assert main([*argv, str(disk / 'out')]) == 2
    (line,) = [x for x in capsys.readouterr().err.splitlines() if x.startswith('folder-line')]
    assert line == f"folder-line: error: {option}='{disk / 'out' / name}': cannot write: No space left on device"
    assert snapshot(disk, folder_mtimes=False) == before


def _read_only_folder(tmp_path: Path, small_tmpfs: Callable[[str], Path]) -> tuple[Path, str]:
    """A folder nobody may write into, and the OS reason the writer will see."""
    if not ROOT:
        ro = tmp_path / 'ro'
        ro.mkdir()
        ro.chmod(0o555)
        return ro, 'Permission denied'
    return small_tmpfs('ro,size=16k'), 'Read-only file system'  # root ignores permission bits


@pytest.mark.parametrize('verb', [*FILE_VERBS, *FOLDER_VERBS])
def test_read_only_folder(
    tmp_path: Path, run_dir: Path, small_tmpfs: Callable[[str], Path], capsys: pytest.CaptureFixture[str], verb: str
) -> None:
    ro, reason = _read_only_folder(tmp_path, small_tmpfs)
    try:
        before = snapshot(ro)
        if verb in FILE_VERBS:
            line = refused(_file_argv(verb, ro / 'x.out'), capsys)
            assert line == f"folder-line: error: {verb.split()[1]}='{ro / 'x.out'}': cannot write: {reason}"
        else:
            for out in (ro, ro / 'sub'):  # the folder itself (a run's probe), a folder to create in it
                line = refused(_folder_argv(verb, run_dir, out), capsys)
                assert line.startswith(f"folder-line: error: --out='{out}': cannot ") and line.endswith(reason), line
        assert snapshot(ro) == before
    finally:
        if not ROOT:
            ro.chmod(0o755)


@pytest.mark.parametrize('verb', [*FILE_VERBS, 'report'])
def test_permission_denied_injected(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], verb: str
) -> None:
    import tempfile

    def denied(*args: Any, **kwargs: Any) -> Any:
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), kwargs.get('dir'))

    out = tmp_path / 'out'
    out.mkdir()
    monkeypatch.setattr(tempfile, 'mkstemp', denied)
    before = snapshot(tmp_path, folder_mtimes=False)
    argv = _file_argv(verb, out / 'x.out') if verb in FILE_VERBS else _folder_argv(verb, tmp_path, out)
    line = refused(argv, capsys)
    assert line.endswith(': Permission denied') and f"='{out}" in line, line
    assert snapshot(tmp_path, folder_mtimes=False) == before


def test_a_write_refused_deep_inside_a_run_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import folder_line.ros.run

    out = tmp_path / 'out'
    segment = out / 'bag' / 'bag_0.mcap'

    def full(cfg: Any, *rest: Any) -> Any:  # the bag writer meets a full disk (no ROS needed to show the CLI)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(segment))

    monkeypatch.setattr(folder_line.ros.run, 'run_line', full)
    line = refused(['run', '--duration', '1', '--out', str(out)], capsys)
    assert line == f"folder-line: error: --out: '{segment}': No space left on device"
    assert list(tmp_path.iterdir()) == []  # the folder the claim made, still empty, is gone


# --------------------------------------------------------------------------- found by a hostile trial


def test_analyze_checks_every_csv_target_before_it_writes_anything(
    tmp_path: Path, run_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from folder_line.analysis import csv_name

    out = tmp_path / 'analysis'
    (out / 'csv').mkdir(parents=True)
    os.mkfifo(out / 'csv' / csv_name('/clock'))
    before = snapshot(out, folder_mtimes=False)  # (the claim's write probe touches the folder's mtime)
    line = refused(['analyze', str(run_dir), '--out', str(out), '--csv'], capsys)
    assert 'clock.csv' in line and 'is a FIFO, not a regular file' in line
    assert snapshot(out, folder_mtimes=False) == before  # no figure, no CSV written before the refusal


def test_a_very_long_path_keeps_its_end_and_the_os_reason(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with _cwd(tmp_path):
        name = 'f/' + 'a' * 5000
        line = refused(['kinematics', 'layup', '--samples', '4', '--csv', name], capsys)
        assert len(line) < 400 and line.endswith("aaa': File name too long"), line
        line = refused(['simulate', '--duration', '1', '--scene', 'in/' + 'b' * 300 + '.yaml'], capsys)
        assert line.startswith("folder-line: error: --scene='in/bbb") and len(line) < 400, line


@pytest.mark.parametrize(
    ('make', 'words'),
    [
        (_fifo, 'metadata.yaml: is a FIFO, not a regular file'),
        (_dir, 'metadata.yaml: is a directory, not a regular file'),
        (lambda p: p.write_text(''), 'metadata.yaml: line 1, column 1: not rosbag2 metadata'),
        (lambda p: p.write_text('- 1\n- 2\n'), 'metadata.yaml: line 1, column 1: not rosbag2 metadata'),
    ],
    ids=['fifo', 'directory', 'empty', 'list'],
)
def test_bag_info_names_what_is_wrong_with_the_metadata(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], make: Callable[[Path], None], words: str
) -> None:
    bag = tmp_path / 'bag'
    bag.mkdir()
    make(bag / 'metadata.yaml')
    before = snapshot(bag)
    for argv in (['bag', 'info', str(bag)], ['analyze', str(bag), '--out', str(tmp_path / 'a')]):
        line = refused(argv, capsys)
        assert words in line, line
    assert snapshot(bag) == before and not (tmp_path / 'a').exists()


@pytest.mark.parametrize(
    ('make', 'words'),
    [(_file, 'is a regular file'), (_fifo, 'is a FIFO'), (_dangling, 'is a symbolic link to nothing (dangling)')],
    ids=['file', 'fifo', 'dangling'],
)
def test_analyze_says_what_its_path_is_when_it_is_no_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], make: Callable[[Path], None], words: str
) -> None:
    target = tmp_path / 'x'
    make(target)
    line = refused(['analyze', str(target)], capsys)
    assert f"RUN_DIR|BAG='{target}': {words}, not a run directory or a bag directory" in line, line


def test_a_set_item_without_a_value_is_named(capsys: pytest.CaptureFixture[str]) -> None:
    line = refused(['simulate', '--duration', '1', '--set', 'knife.n_k='], capsys)
    assert line == "folder-line: error: knife.n_k='': needs a value (KEY=VALUE)"


def test_run_names_the_duration_it_was_given(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Past the longest line time (1e7 s, the time resolution: memory no longer bounds it), in one line,
    as written, and nothing made."""
    with pytest.raises(SystemExit) as info:  # the parser's refusal
        main(['run', '--duration', '2e7', '--out', str(tmp_path / 'out')])
    assert info.value.code == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert err.startswith('folder-line run: error: ') and "--duration='2e7'" in err and '10000000' in err, err
    assert not (tmp_path / 'out').exists()
