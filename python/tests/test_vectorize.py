"""The package as a user calls it: paths, bytes, arrays, automatic budgets, bad input."""

import os
import pathlib
import re
import struct
import subprocess
import sys
import threading
import time
import zlib

import numpy
import pytest

import supersvg

ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "assets" / "astronaut.jpg"


def paths_in(svg):
    return len(re.findall(r"<path\b", svg))


def flat_art(height=48, width=64):
    """A red disc on blue with a transparent corner: RGBA uint8."""
    y, x = numpy.mgrid[0:height, 0:width]
    pixels = numpy.zeros((height, width, 4), numpy.uint8)
    pixels[..., 2] = 200
    pixels[..., 3] = 255
    disc = (x - 40) ** 2 + (y - 24) ** 2 < 15**2
    pixels[disc] = [220, 30, 30, 255]
    pixels[:10, :10, 3] = 0
    return pixels


def test_a_file_path_gives_an_svg_of_the_budget_and_the_files_size():
    svg = supersvg.vectorize(EXAMPLE, paths=40, size=128)
    assert svg.startswith("<svg") or svg.startswith("<?xml")
    assert 2 <= paths_in(svg) <= 40
    assert 'width="512"' in svg and 'height="512"' in svg  # the file's size, not the working one
    assert supersvg.vectorize(str(EXAMPLE), paths=40, size=128) == svg  # str and Path alike


def test_bytes_draw_what_their_file_draws(tmp_path):
    data = EXAMPLE.read_bytes()
    out = tmp_path / "astronaut.svg"
    svg = supersvg.vectorize(data, paths=40, size=128, out=out)
    assert svg == supersvg.vectorize(EXAMPLE, paths=40, size=128)
    assert out.read_text() == svg
    assert os.listdir(tmp_path) == ["astronaut.svg"]  # no temporary left beside it


def test_arrays_rgb_rgba_and_grey_are_drawn_with_their_colours():
    rgba = flat_art()
    svg = supersvg.vectorize(rgba, paths=8)
    assert 'width="64"' in svg and 'height="48"' in svg
    # The disc's red and the blue are in the drawing; the transparent corner is drawn over white.
    fills = set(re.findall(r'fill="(#[0-9a-f]{6})"', svg.lower()))
    assert any(int(f[1:3], 16) > 180 and int(f[5:7], 16) < 80 for f in fills), fills
    assert any(int(f[5:7], 16) > 150 and int(f[1:3], 16) < 60 for f in fills), fills
    rgb = numpy.ascontiguousarray(rgba[..., :3])
    assert paths_in(supersvg.vectorize(rgb, paths=8)) >= 2
    grey = rgba[..., 0]
    assert paths_in(supersvg.vectorize(grey[:, ::-1], paths=8)) >= 2  # not C-contiguous: copied


def test_auto_budget_draws_flat_art_with_few_paths():
    svg = supersvg.vectorize(flat_art(), paths="auto")
    assert 2 <= paths_in(svg) < 40


def test_finetune_secs_runs_superSVG_F():
    started = time.monotonic()
    base = supersvg.vectorize(EXAMPLE, paths=20, size=64)
    tuned = supersvg.vectorize(EXAMPLE, paths=20, size=64, finetune_secs=0.5)
    assert time.monotonic() - started >= 0.5
    assert tuned != base


def test_fills_draw_ramps_as_gradients_when_asked():
    flat = supersvg.vectorize(EXAMPLE, paths=40, size=128, fills="flat")
    linear = supersvg.vectorize(EXAMPLE, paths=40, size=128, fills="linear")
    assert "<linearGradient" not in flat
    assert linear.count("<linearGradient") == linear.count('fill="url(#') >= 10
    # The default is auto for SuperSVG-B.
    default = supersvg.vectorize(EXAMPLE, paths=40, size=128)
    assert default == supersvg.vectorize(EXAMPLE, paths=40, size=128, fills="auto") != flat
    with pytest.raises(ValueError, match="not a fill"):
        supersvg.vectorize(EXAMPLE, fills="smooth")
    with pytest.raises(ValueError, match="fills"):
        supersvg.vectorize(EXAMPLE, fills=3)


def test_bad_input_is_a_python_exception_naming_the_problem(tmp_path):
    with pytest.raises(ValueError, match="not an image in a known format"):
        supersvg.vectorize(b"plain text, not an image")
    broken = tmp_path / "broken.png"
    broken.write_bytes(EXAMPLE.read_bytes()[:300])
    with pytest.raises(ValueError, match="broken.png"):
        supersvg.vectorize(broken)
    with pytest.raises(FileNotFoundError, match="missing.png"):
        supersvg.vectorize(tmp_path / "missing.png")
    with pytest.raises(ValueError, match="out of range"):
        supersvg.vectorize(EXAMPLE, paths=1)
    with pytest.raises(ValueError, match="'many'"):
        supersvg.vectorize(EXAMPLE, paths="many")
    with pytest.raises(ValueError, match="float64"):
        supersvg.vectorize(numpy.zeros((8, 8, 3)))
    with pytest.raises(ValueError, match="shape"):
        supersvg.vectorize(numpy.zeros((8, 8, 2), numpy.uint8))
    with pytest.raises(ValueError, match="empty"):
        supersvg.vectorize(numpy.zeros((0, 8, 3), numpy.uint8))
    with pytest.raises(ValueError, match="size 4"):
        supersvg.vectorize(EXAMPLE, size=4)
    with pytest.raises(TypeError, match="int"):
        supersvg.vectorize(42)
    with pytest.raises(OSError, match="no-such-folder"):
        supersvg.vectorize(flat_art(), paths=4, out=tmp_path / "no-such-folder" / "out.svg")
    assert not (tmp_path / "no-such-folder").exists()


def test_huge_numbers_are_value_errors():
    for kwargs in [dict(paths=10**30), dict(size=10**12), dict(size=2**32), dict(finetune_secs=10**400)]:
        with pytest.raises(ValueError):
            supersvg.vectorize(EXAMPLE, **kwargs)


def test_out_is_never_the_input_and_is_checked_before_work(tmp_path):
    victim = tmp_path / "victim.png"
    victim.write_bytes(EXAMPLE.read_bytes())
    with pytest.raises(ValueError, match=r"must end in \.svg"):
        supersvg.vectorize(victim, paths=20, size=64, out=victim)
    link = tmp_path / "link.svg"
    link.symlink_to(victim)
    with pytest.raises(ValueError, match="refusing to overwrite"):
        supersvg.vectorize(victim, paths=20, size=64, out=link)
    assert victim.read_bytes() == EXAMPLE.read_bytes()
    # A name the file system cannot hold is refused before the work; the longest it holds works.
    with pytest.raises(OSError, match="longer than"):
        supersvg.vectorize(EXAMPLE, paths=20, size=64, out=tmp_path / ("n" * 252 + ".svg"))
    longest = tmp_path / ("n" * 251 + ".svg")
    assert supersvg.vectorize(EXAMPLE, paths=20, size=64, out=longest) == longest.read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["link.svg", "victim.png", longest.name])


def test_too_few_paths_is_said_as_a_warning():
    flat = numpy.full((32, 32, 3), 120, numpy.uint8)
    with pytest.warns(UserWarning, match="of 50 paths drawn"):
        svg = supersvg.vectorize(flat, paths=50)
    assert paths_in(svg) == 1


def test_the_gil_is_released_while_it_works():
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.005)

    supersvg.vectorize(EXAMPLE, paths=20, size=64)  # models loaded before timing
    counter = threading.Thread(target=count)
    counter.start()
    started = time.monotonic()
    # Fine-tuning for a fixed time makes the call last, however fast the machine draws.
    supersvg.vectorize(EXAMPLE, paths=300, size=256, finetune_secs=0.5)
    took = time.monotonic() - started
    done.set()
    counter.join()
    during = [t for t in ticks if started < t < started + took]
    # Held, the other thread would not run at all until the call returned: not one tick of it
    # would fall inside the call (how many do depends on the machine's load, so none is counted).
    assert took > 0.5 and during, (took, len(ticks))


def test_ctrl_c_stops_a_long_fine_tuning():
    import signal

    supersvg.vectorize(EXAMPLE, paths=20, size=64)  # models loaded before timing
    timer = threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT))
    started = time.monotonic()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        supersvg.vectorize(EXAMPLE, paths=50, size=128, finetune_secs=60)
    assert time.monotonic() - started < 20


def huge_black_png(path, side):
    """A side × side black RGB PNG, written in moments: its deflate stream is one block of rows
    repeated (each ends in a full flush, so each compresses alike), and its Adler-32 is that of
    zeros."""

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    row, rows = 1 + 3 * side, 64
    assert side % rows == 0
    compressor = zlib.compressobj(1)
    head = compressor.compress(bytes(row * rows)) + compressor.flush(zlib.Z_FULL_FLUSH)
    unit = compressor.compress(bytes(row * rows)) + compressor.flush(zlib.Z_FULL_FLUSH)
    tail = compressor.flush(zlib.Z_FINISH)[:-4]
    adler = struct.pack(">I", (((row * side) % 65521) << 16) | 1)
    header = struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0)
    with open(path, "wb") as out:
        out.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header))
        out.write(chunk(b"IDAT", head + unit * (side // rows - 2)))
        out.write(chunk(b"IDAT", unit + tail + adler))
        out.write(chunk(b"IEND", b""))


def test_ctrl_c_stops_the_read_of_a_huge_image(tmp_path):
    import signal

    huge = tmp_path / "huge.png"
    huge_black_png(huge, 40000)  # read row by row: seconds of work
    supersvg.vectorize(EXAMPLE, paths=20, size=64)  # models loaded before timing
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    started = time.monotonic()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        supersvg.vectorize(huge, paths=10)
    # The read alone takes several seconds; the interrupt is heard within a poll of it.
    assert time.monotonic() - started < 2.5


def test_finetune_secs_takes_a_number_and_names_itself():
    for value in ["2", b"2", [2]]:
        with pytest.raises(ValueError, match="finetune_secs"):
            supersvg.vectorize(EXAMPLE, paths=20, size=64, finetune_secs=value)
    for value in [1e9, -1, float("nan")]:
        with pytest.raises(ValueError, match="finetune_secs"):
            supersvg.vectorize(EXAMPLE, paths=20, size=64, finetune_secs=value)


def test_a_models_folder_without_a_mover_serves_jobs_that_do_not_move(tmp_path):
    models = ROOT / "models"
    for name in ["coarse.ckpt", "refine.ckpt"]:
        (tmp_path / name).write_bytes((models / name).read_bytes())
    script = (
        "import supersvg, sys\n"
        f"svg = supersvg.vectorize({str(EXAMPLE)!r}, paths=20, size=64, fills='flat')\n"
        "assert svg.startswith('<svg')\n"
        "try:\n"
        f"    supersvg.vectorize({str(EXAMPLE)!r}, paths=20, size=64, moves='on')\n"
        "except RuntimeError as err:\n"
        "    assert 'mover.ckpt' in str(err), err\n"
        "else:\n"
        "    sys.exit('a job that moves ran without a mover')\n"
    )
    env = dict(os.environ, SUPERSVG_MODELS=str(tmp_path))
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr


def test_moves_choose_where_the_mover_runs():
    moved = supersvg.vectorize(EXAMPLE, paths=100, size=128)
    assert moved == supersvg.vectorize(EXAMPLE, paths=100, size=128, moves="auto")
    drawn = supersvg.vectorize(EXAMPLE, paths=100, size=128, moves="off")
    assert moved != drawn  # the example is a photo: the mover moves its outlines
    # By default flat fills are left as drawn; "on" moves them too.
    flat = supersvg.vectorize(EXAMPLE, paths=100, size=128, fills="flat")
    assert flat == supersvg.vectorize(EXAMPLE, paths=100, size=128, fills="flat", moves="off")
    assert flat != supersvg.vectorize(EXAMPLE, paths=100, size=128, fills="flat", moves="on")
    with pytest.raises(ValueError, match="moves"):
        supersvg.vectorize(EXAMPLE, moves="sometimes")
    with pytest.raises(ValueError, match="moves"):
        supersvg.vectorize(EXAMPLE, moves=False)
