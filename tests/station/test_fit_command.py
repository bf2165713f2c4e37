"""`station fit` on bundled real garments: the numbers, the picture and the errors."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from solver.fit import fit_report
from solver.garment import load_garment
from solver.placement import Placement
from solver.wallpaper import Wallpaper
from station.cli import main

FABRIC = {"group": "p4m", "w1": [5, 0], "w2": [0, 5], "origin": [1, 2], "units": "cm"}


@pytest.fixture
def fabric(tmp_path):
    path = tmp_path / "fabric.json"
    path.write_text(json.dumps(FABRIC))
    return path


def run_json(capsys, *argv) -> dict:
    assert main(list(argv)) == 0
    return json.loads(capsys.readouterr().out)


def test_fit_reports_e_fit_of_the_identity_and_of_a_placement(tmp_path, fabric, capsys,
                                                              data_dir):
    path = data_dir / "garments" / "berkeley" / "shorts-iso.obj"
    out = run_json(capsys, "fit", str(path), "--units", "m", "--fabric", str(fabric), "--json")
    garment = load_garment(path, units="m")
    wp = Wallpaper.from_dict(FABRIC)
    expected = fit_report(garment, Placement.identity(garment.n_pieces, wp))
    assert out["pieces"] == 4 and out["seam_edges"] == 104
    assert out["e_fit_mm2"] == pytest.approx(expected.e_fit_mm2, rel=1e-12)
    assert out["e_fit_cm2"] == pytest.approx(expected.e_fit_mm2 / 100, rel=1e-12)
    assert out["e_fit_mm2"] > 1000.0  # a random placement of a 50 mm check does not fit
    # A written placement is honoured.
    rng = np.random.default_rng(1)
    placement = Placement(rng.uniform(0, 6, 4), rng.uniform(-50, 50, (4, 2)), wp)
    placement.save(tmp_path / "placement.json")
    out2 = run_json(capsys, "fit", str(path), "--units", "m", "--fabric", str(fabric),
                    "--placement", str(tmp_path / "placement.json"), "--json")
    assert out2["e_fit_mm2"] == pytest.approx(fit_report(garment, placement).e_fit_mm2)
    assert out2["e_fit_mm2"] != pytest.approx(out["e_fit_mm2"])


def test_fit_png_shows_pieces_over_the_print_with_coloured_seams(tmp_path, fabric, capsys,
                                                                 data_dir):
    path = data_dir / "garments" / "berkeley" / "tshirt-coarse.obj"
    png = tmp_path / "fit.png"
    out = run_json(capsys, "fit", str(path), "--units", "m", "--fabric", str(fabric),
                   "--png", str(png), "--json")
    image = cv2.imread(str(png))
    assert image is not None and image.shape[1] == 1600
    background = np.all(image == 245, axis=2).mean()
    assert 0.2 < background < 0.9  # pieces cover part of the picture
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    seam_like = (hsv[..., 1] > 200) & (hsv[..., 2] > 150)
    assert seam_like.sum() > 500  # saturated green-to-red seam strokes are drawn
    assert out["png"] == str(png)


@pytest.mark.parametrize(
    ("fabric_text", "message"),
    [
        ('{"group": "p4", "w1": [40, 0], "w2": [0, 41]}', "lattice does not fit group p4"),
        ('{"group": "p7", "w1": [40, 0], "w2": [0, 40]}', "unknown wallpaper group"),
        ('{"group": "p4"', "not valid JSON"),
    ],
)
def test_bad_fabric_is_one_clear_line(tmp_path, capsys, data_dir, fabric_text, message):
    path = tmp_path / "fabric.json"
    path.write_text(fabric_text)
    garment = data_dir / "garments" / "berkeley" / "pants-coarse.obj"
    assert main(["fit", str(garment), "--units", "m", "--fabric", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and str(path) in err and "\n" not in err


def test_missing_files_and_wrong_placement(tmp_path, fabric, capsys, data_dir):
    garment = data_dir / "garments" / "berkeley" / "pants-coarse.obj"
    assert main(["fit", str(tmp_path / "none.obj"), "--fabric", str(fabric)]) == 2
    assert "no such garment file" in capsys.readouterr().err
    Placement.identity(3, Wallpaper.from_dict(FABRIC)).save(tmp_path / "p.json")
    assert main(["fit", str(garment), "--units", "m", "--fabric", str(fabric),
                 "--placement", str(tmp_path / "p.json")]) == 2
    assert "placement has 3 pieces" in capsys.readouterr().err


def test_an_allowance_without_a_picture_is_checked_and_said_to_change_nothing(
        tmp_path, fabric, capsys, data_dir):
    """The fit is measured on the sew line: an allowance only changes ``--png``. It was
    ignored without a word, and a bad allowance file was never read."""
    path = data_dir / "garments" / "berkeley" / "shorts-iso.obj"
    common = ["fit", str(path), "--units", "m", "--fabric", str(fabric), "--json"]
    plain = run_json(capsys, *common)
    with_allowance = run_json(capsys, *common, "--seam-allowance", "15")
    assert with_allowance["e_fit_mm2"] == pytest.approx(plain["e_fit_mm2"], rel=1e-12)
    capsys.readouterr()
    main([*common, "--seam-allowance", "15"])
    assert "warning: the allowance only changes the --png picture" in capsys.readouterr().err
    bad = tmp_path / "A.json"
    bad.write_text('{"seam": -4}')
    assert main([*common, "--allowance", str(bad)]) == 2
    assert str(bad) in capsys.readouterr().err


def test_a_picture_option_naming_no_picture_format_is_refused_before_any_work(tmp_path, capsys):
    """`fit --png x.json` computed the fit, then died in the image writer (exit 70)."""
    from station.cli import main

    with pytest.raises(SystemExit) as refused:
        main(["fit", "spec.json", "--fabric", "fabric.json", "--png", str(tmp_path / "x.json")])
    assert refused.value.code == 2
    assert "x.json: a picture is written as .png" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()
