"""A missing or broken URDF is one clear :class:`wbc.ModelLoadError` naming the file and the
parser's reason, with nothing printed by the C++ parser (checked at the file-descriptor level)."""

from __future__ import annotations

import pytest

import wbc
import wbc.robots as robots

BROKEN = {
    "not_xml.urdf": ("this is not XML", "XML_ERROR"),
    "no_limits.urdf": ('<robot name="r"><link name="a"/><link name="b"/>'
                       '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
                       "</joint></robot>", "does not specify limits"),
}


def test_a_missing_urdf(tmp_path, capfd):
    path = tmp_path / "nowhere.urdf"
    with pytest.raises(wbc.ModelLoadError, match="nowhere.urdf' does not exist"):
        robots.from_urdf(path, base="mecanum", ee_frame="tool0")
    assert capfd.readouterr() == ("", "")


@pytest.mark.parametrize("name", BROKEN)
def test_a_broken_urdf(tmp_path, capfd, name):
    text, reason = BROKEN[name]
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(wbc.ModelLoadError, match=f"{name}' cannot be loaded: .*{reason}"):
        robots.from_urdf(path, base="omni", ee_frame="tool0")
    assert capfd.readouterr() == ("", "")


def test_a_valid_urdf_still_loads():
    path = robots.urdf_path("ur_description/urdf/ur5_robot.urdf")
    robot = robots.from_urdf(path, base="mecanum", ee_frame="tool0")
    assert robot.nv == 3 + 6
