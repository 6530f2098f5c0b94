"""Namelist syntax users write: several groups on a line, upper case, comments, '!' and '/'
inside strings, array elements and repeat counts all read as Fortran would read them."""
import subprocess

import numpy as np

from conftest import BIN, read_run


def run_text(tmp_path, text):
    namelist = tmp_path / "scene.nml"
    namelist.write_text(text)
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return result


def test_groups_on_one_line_upper_case_and_comments(tmp_path, eme_run_binary):
    output = tmp_path / "odd!name" / "run.h5"
    run_text(tmp_path, f"! a comment line\n&INTEGRATOR DT = 0.1, T_END=0.3 / &output file = '{output}' ! why\n/\n"
                       "&initial theta(2) = 360.0  p2(1:2) = 2*0.5 /\n&model mass = 2*1.5 /\n")
    data = read_run(output)
    assert data["attrs"]["dt"] == 0.1 and data["attrs"]["t_end"] == 0.3
    np.testing.assert_allclose(data["attrs"]["theta"], [280.0, 360.0])
    np.testing.assert_allclose(data["attrs"]["p2"], [0.5, 0.5, 0.0])
    np.testing.assert_allclose(data["attrs"]["mass"], [1.5, 1.5])
    np.testing.assert_allclose(data["temperature"][0], [280.0, 360.0])


def test_an_assignment_repeated_is_refused_not_overwritten(tmp_path, eme_run_binary):
    """Fortran's namelist READ lets the later assignment win; a repeated field is more often a
    copy-paste slip than intent, so it is refused, naming the field, and nothing is written."""
    output = tmp_path / "run.h5"
    namelist = tmp_path / "scene.nml"
    namelist.write_text(f"&integrator dt = 0.2, t_end = 0.4, DT = 0.1 /\n&output file = '{output}' /\n")
    result = subprocess.run([str(BIN / "eme_run"), str(namelist)], capture_output=True, text=True)
    assert result.returncode == 2
    assert "&integrator: dt is given twice" in result.stderr
    assert not output.exists()


def test_long_lines_and_a_last_line_without_newline(tmp_path, eme_run_binary):
    output = tmp_path / "run.h5"
    padding = " " * 3000
    run_text(tmp_path, f"&integrator dt = 0.2,{padding} t_end = 0.4 /\n&output file = '{output}' /")
    data = read_run(output)
    assert data["attrs"]["t_end"] == 0.4 and data["attrs"]["status"] == "complete"


def test_tabs_crlf_and_special_characters_inside_quotes(tmp_path, eme_run_binary):
    """The strict reader still takes what Fortran's namelist input takes: tab separators, DOS
    line ends, '/', '&' and '!' and a doubled quote inside quoted texts, empty groups, and
    comments and blank lines between groups."""
    output = tmp_path / "a&b!c's" / "run/x.h5"
    quoted = str(output).replace("'", "''")
    text = ("! scene\r\n\r\n&integrator\tdt = 0.1,\tt_end = 0.3 /\r\n"
            "   ! between groups\r\n&constraints /\r\n"
            f"&output file = '{quoted}' ! a comment with ' and & and /\r\n/\r\n")
    run_text(tmp_path, text)
    data = read_run(output)
    assert data["attrs"]["dt"] == 0.1 and data["attrs"]["t_end"] == 0.3


def test_array_element_and_range_assignments_combine(tmp_path, eme_run_binary):
    """theta(2) and p2(2:3) set only their elements; the others keep their defaults."""
    output = tmp_path / "run.h5"
    run_text(tmp_path, f"&integrator t_end = 0.3 /\n&initial theta(2) = 340, p2(2:3) = -0.5, 0.25 /\n"
                       f"&output file = '{output}' /\n")
    data = read_run(output)
    np.testing.assert_allclose(data["attrs"]["theta"], [280.0, 340.0])
    np.testing.assert_allclose(data["attrs"]["p2"], [-1.0, -0.5, 0.25])
