"""Outputs written through a temporary file and a rename: a named pipe or a device (``-o /dev/null``) is written
into, never renamed over (as root the rename replaced /dev/null with a regular file, and every later program
that wrote to it as another user failed), and a link is followed (the file it names replaced, the link kept)."""
import os
import stat
import threading

import kincal
from kincal._atomic import AtomicFile, write_text_atomic
from kincal.cli import main


def test_a_named_pipe_is_written_into_not_replaced(tmp_path):
    fifo = tmp_path / "out.csv"
    os.mkfifo(fifo)
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(open(fifo).read()), daemon=True)
    reader.start()
    write_text_atomic(fifo, "j1,j2\n0.1,0.2\n")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)  # before: a regular file in the pipe's place, the reader left waiting
    reader.join()
    assert got == ["j1,j2\n0.1,0.2\n"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]  # no temporary file left


def test_a_pipe_gets_nothing_when_the_text_is_not_kept(tmp_path):
    fifo = tmp_path / "out.csv"
    os.mkfifo(fifo)
    with AtomicFile(fifo) as fh:
        fh.write("half")  # not kept: nothing is opened, so no reader is needed
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


def test_a_link_is_followed(tmp_path):
    real = tmp_path / "real.yaml"
    real.write_text("old\n")
    link = tmp_path / "link.yaml"
    link.symlink_to(real)
    write_text_atomic(link, "new\n")
    assert link.is_symlink() and os.readlink(link) == str(real) and real.read_text() == "new\n"


def test_the_command_line_writes_into_a_pipe(tmp_path):
    """`kincal simulate ... -o PIPE` (as `-o /dev/null` or `-o /dev/stdout`, not tried here: a regression would
    replace the machine's /dev/null) writes the CSV into the pipe, which stays a pipe."""
    fifo = tmp_path / "poses.csv"
    os.mkfifo(fifo)
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(open(fifo).read()), daemon=True)
    reader.start()
    assert main(["simulate", "ur5", "--poses", "5", "-o", str(fifo)]) == 0
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)  # (before: a file in its place, the reader left waiting)
    reader.join()
    assert got[0].splitlines()[0].startswith("j1,") and len(got[0].splitlines()) == 6  # header and 5 poses


def _kincal():
    import sys
    from pathlib import Path
    return str(Path(sys.executable).parent / "kincal")


def test_dev_stdout_into_a_pipe_and_into_a_redirected_file(tmp_path):
    """`-o /dev/stdout | ...` ended in 'No such file or directory: /proc/.../fd/.pipe:[...]' (the temporary file
    went beside the link's target), and `-o /dev/stdout > r.txt` lost kincal's own line after the CSV (the file was
    renamed over while the shell held it open). Both give the CSV alone on the standard output now, kincal's line
    on the standard error (in the stream it made the file unreadable: 'row 5 has 1 fields')."""
    import subprocess
    argv = [_kincal(), "simulate", "ur5", "--poses", "3", "-o", "/dev/stdout"]
    piped = subprocess.run(argv, capture_output=True, text=True, cwd=tmp_path)
    assert piped.returncode == 0, piped.stderr
    with open(tmp_path / "r.csv", "w") as out:
        redirected = subprocess.run(argv, stdout=out, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    assert redirected.returncode == 0, redirected.stderr
    for text, said in ((piped.stdout, piped.stderr), ((tmp_path / "r.csv").read_text(), redirected.stderr)):
        lines = text.splitlines()
        assert lines[0] == "j1,j2,j3,j4,j5,j6,x,y,z" and [len(x.split(",")) for x in lines[1:]] == [9, 9, 9]
        assert said.strip() == "wrote 3 simulated measurements of ur5 to /dev/stdout"
    ur5 = kincal.load_robot("ur5")
    back = kincal.read_measurements(str(tmp_path / "r.csv"), ur5)  # the file reads back as data
    assert back.q.shape == (3, 6)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv"]


def test_a_robot_file_through_the_standard_output_loads_back(tmp_path):
    """`kincal export cal.yaml /dev/stdout > exp.yaml`: the YAML ended with export's own lines (not valid YAML)
    while export said it was checked; now the stream holds the robot file alone, which loads as the model."""
    import subprocess
    with open(tmp_path / "exp.yaml", "w") as out:
        done = subprocess.run([_kincal(), "export", "ur5", "/dev/stdout"], stdout=out, stderr=subprocess.PIPE,
                              text=True, cwd=tmp_path)
    assert done.returncode == 0 and "yaml written to /dev/stdout" in done.stderr
    assert kincal.load_robot(str(tmp_path / "exp.yaml")).params == kincal.load_robot("ur5").params
