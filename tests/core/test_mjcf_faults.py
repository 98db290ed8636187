"""The fifth fault battery (issue 54), its MJCF rows: a model read as MuJoCo reads it. One cap
on the bytes of a model and its includes, numbers as strtod reads them, and the messages of a
too-deep nesting, a reversed range and a repeated default class naming the file and the fault.
Each test names its row of docs/faults.md; every row has a variant the issue did not list."""
import time

import numpy as np
import pytest

from gbmodel import mjcf, urdf


def _one_line(err) -> str:
    assert "\n" not in str(err.value), str(err.value)
    return str(err.value)

CHAIN = ("<worldbody><body name='b'><joint name='j' {joint}/>"
         "<body name='c' pos='{pos}'><site name='t'/></body></body></worldbody>")


def _mjcf(tmp_path, name="m.xml", pos="0.3 0 0", joint="", head=""):
    path = tmp_path / name
    path.write_text(f"<mujoco>{head}{CHAIN.format(pos=pos, joint=joint)}</mujoco>")
    return str(path)


def _refused(file, says):
    t = time.perf_counter()
    with pytest.raises(ValueError) as err:
        mjcf.read_chain(file, "world", "t")
    assert says in _one_line(err) and time.perf_counter() - t < 20, str(err.value)
    return str(err.value)


def _big(tmp_path, name, size):
    with open(tmp_path / name, "wb") as fh:
        fh.write(b"<mujoco>")
        fh.write(b" " * (size - len(b"<mujoco></mujoco>")))
        fh.write(b"</mujoco>")


def test_r7_one_byte_cap_per_model_across_its_includes(tmp_path):
    _big(tmp_path, "big.xml", 15 * 2**20)
    _refused(_mjcf(tmp_path, head="<include file='big.xml'/>" * 63), "may hold in all")
    # variant: two different includes, each under the cap, together over it
    _big(tmp_path, "a.xml", 9 * 2**20)
    _big(tmp_path, "b.xml", 9 * 2**20)
    _refused(_mjcf(tmp_path, head="<include file='a.xml'/><include file='b.xml'/>"),
             "<include file='b.xml'>")
    assert len(mjcf.read_chain(_mjcf(tmp_path, head="<include file='a.xml'/>"), "world",
                               "t")["names"]) == 1


def test_r10_nesting_too_deep_names_the_file(tmp_path):
    deep = "<body>" * 300 + "</body>" * 300
    msg = _refused(_mjcf(tmp_path, head=f"<worldbody>{deep}</worldbody>"), "nested more than")
    assert "m.xml" in msg
    # variant: in an included file, which the message names
    (tmp_path / "inc.xml").write_text(f"<mujoco><worldbody>{deep}</worldbody></mujoco>")
    assert "inc.xml: elements nested" in _refused(_mjcf(tmp_path, head="<include file="
                                                                       "'inc.xml'/>"), "nested")


@pytest.mark.parametrize("pos", ["1_0 0 0", "0x10 0 0", "\u0661 0 0", "1e5_0 0 0"])
def test_r12_numbers_are_read_as_mujoco_reads_them(tmp_path, pos):
    _refused(_mjcf(tmp_path, pos=pos), "is not a number")


def test_r12_a_urdf_number_alike(tmp_path):
    path = tmp_path / "r.urdf"
    path.write_text("<robot name='r'><link name='a'/><link name='b'/><joint name='j' "
                    "type='revolute'><parent link='a'/><child link='b'/><origin xyz='1_0 0 0'/>"
                    "<axis xyz='0 0 1'/><limit lower='-1' upper='1'/></joint></robot>")
    with pytest.raises(ValueError, match="'1_0' is not a number"):
        urdf.read_chain(str(path), "a", "b")


def test_r14_a_reversed_range_is_reported_as_reversed(tmp_path):
    _refused(_mjcf(tmp_path, joint="range='1 -1'"), "range '1 -1' is reversed")
    _refused(_mjcf(tmp_path, joint="range='0.5 0.5' limited='true'"), "empty")  # variant
    # variant: an unlimited joint's range is not read, as MuJoCo ignores it
    chain = mjcf.read_chain(_mjcf(tmp_path, joint="range='1 -1' limited='false'"), "world", "t")
    assert np.isnan(chain["limits"]).all()


def test_r16_a_repeated_default_class_is_refused(tmp_path):
    twice = "<default><default class='a'/><default class='a'/></default>"
    _refused(_mjcf(tmp_path, head=twice), "<default class='a'>: a default class of that name")
    # variants: the second one nested, in an include; a nested class without a name
    (tmp_path / "d.xml").write_text("<mujoco><default><default class='a'/></default></mujoco>")
    _refused(_mjcf(tmp_path, head="<default><default class='a'><default class='b'/></default>"
                                  "</default><include file='d.xml'/>"), "defined twice")
    _refused(_mjcf(tmp_path, head="<default><default/></default>"), "needs its name")
