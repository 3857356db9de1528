"""What a newcomer finds in each archive: documentation/index.html with the paper, the
modes and a working fmpy example, the licence, an icon, the input file of the documented
first run, and who made the XML when under which licence."""

import html
import re
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
from fmpy import simulate_fmu
from fmpy.util import read_csv

import ehsv

REPO = ehsv.REPO


def archive(version):
    return zipfile.ZipFile(ehsv.fmu_path(version))


def test_archive_carries_documentation_licence_and_icon(version):
    with archive(version) as z:
        names = set(z.namelist())
        page = z.read("documentation/index.html").decode()
        assert z.read("documentation/licenses/license.txt") == (REPO / "LICENSE").read_bytes()
        icon = z.read("model.png")
        root = ET.fromstring(z.read("modelDescription.xml"))
    assert {"documentation/current_step.csv", "model.png"} <= names
    assert icon.startswith(b"\x89PNG\r\n\x1a\n")
    width, height = int.from_bytes(icon[16:20], "big"), int.from_bytes(icon[20:24], "big")
    assert 64 <= width == height <= 512
    assert "Abdulmalek" in page and "Legged Robot's Applications" in page
    for mode in ("ideal_current", "opamp_pi", "hbridge_pid", "position"):
        assert f"<code>{mode}</code>" in page
    assert root.get("license") == "SPDX-License-Identifier: MIT"
    assert root.get("author") and root.get("copyright", "").startswith("Copyright (c) 2026")
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", root.get("generationDateAndTime"))


def test_archive_shows_the_papers_figures(version):
    """Every figure of the gallery (drawn through the FMU) is packed and shown on the page."""
    gallery = sorted(p.name for p in (REPO / "docs" / "gallery").glob("*.png"))
    assert "fig8_opamp_current.png" in gallery
    with archive(version) as z:
        page = z.read("documentation/index.html").decode()
        for name in gallery:
            assert z.read(f"documentation/figures/{name}") == (REPO / "docs" / "gallery" / name).read_bytes()
            assert f"figures/{name}" in page, name


def test_default_experiment_runs_at_rest(version):
    """The documented choice: i_ref starts at 0, so `fmpy simulate` without inputs runs
    and shows the actuator at rest (no command, no motion)."""
    result = simulate_fmu(str(ehsv.fmu_path(version)))
    assert result["time"][-1] > 0
    for name in ("i_coil", "x_spool", "x_piston"):
        assert np.all(result[name] == 0.0), name


def test_documented_input_file_shows_the_current_step(version, tmp_path):
    with archive(version) as z:
        csv = tmp_path / "current_step.csv"
        csv.write_bytes(z.read("documentation/current_step.csv"))
    result = simulate_fmu(
        str(ehsv.fmu_path(version)),
        input=read_csv(str(csv)),
        output_interval=1e-5,
        output=["i_coil", "u_driver"],
    )
    t, i = result["time"], result["i_coil"]
    assert np.all(i[t < 1e-3] == 0.0)
    # The op-amp driver holds 5 mA within 2 % from 0.3 ms after the step on.
    assert np.all(np.abs(i[t > 1.3e-3] - 5e-3) < 0.02 * 5e-3)
    assert result["u_driver"].max() > 60.0  # it drives the coil at the rail first


def test_python_example_of_the_documentation_runs(version, tmp_path, monkeypatch):
    with archive(version) as z:
        page = z.read("documentation/index.html").decode()
    blocks = [html.unescape(b) for b in re.findall(r"<pre>(.*?)</pre>", page, re.S)]
    example = next(b for b in blocks if "simulate_fmu" in b)
    example = example.replace('"EhsvActuator-fmi3.fmu"', repr(str(ehsv.fmu_path(version))))
    namespace = {}
    monkeypatch.chdir(tmp_path)
    exec(compile(example, "index.html example", "exec"), namespace)
    assert abs(namespace["result"]["i_coil"][-1] - 5e-3) < 0.01 * 5e-3


def test_fmi3_terminals_follow_the_schema_and_name_interface_variables():
    import fmpy
    import xmlschema

    with archive("fmi3") as z:
        terminals = z.read("terminalsAndIcons/terminalsAndIcons.xml")
        assert z.read("terminalsAndIcons/icon.png") == z.read("model.png")
        root = ET.fromstring(z.read("modelDescription.xml"))
    schema = Path(fmpy.__file__).parent / "schema" / "fmi3" / "fmi3TerminalsAndIcons.xsd"
    xmlschema.XMLSchema(str(schema)).validate(terminals.decode())
    causality = {v.get("name"): v.get("causality") for v in root.find("ModelVariables")}
    members = [m.get("variableName") for m in ET.fromstring(terminals).iter("TerminalMemberVariable")]
    assert members and all(causality[m] in ("input", "output") for m in members)
