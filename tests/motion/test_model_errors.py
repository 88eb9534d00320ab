"""Bad model files: every problem is one InputError naming the file, the element and the fix."""
from __future__ import annotations

import re

import pytest

from motion.errors import InputError
from motion.osim.reader import load_model

MINIMAL = """<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <Model name="mini">
    <Ground name="ground"/>
    <BodySet name="bodyset"><objects>
      <Body name="thigh">
        <WrapObjectSet><objects>{wrap}</objects></WrapObjectSet>
      </Body>
    </objects></BodySet>
    <JointSet name="jointset"><objects>
      <{joint} name="hip">
        <socket_parent_frame>ground_offset</socket_parent_frame>
        <socket_child_frame>thigh_offset</socket_child_frame>
        <coordinates><Coordinate name="hip_flexion"><range>-1 1</range></Coordinate></coordinates>
        <frames>
          <PhysicalOffsetFrame name="ground_offset"><socket_parent>/ground</socket_parent>
            <translation>0 1 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
          <PhysicalOffsetFrame name="thigh_offset"><socket_parent>/bodyset/thigh</socket_parent>
            <translation>0 0 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
        </frames>
      </{joint}>
    </objects></JointSet>
    <ForceSet name="forceset"><objects>
      <PathActuator name="act">
        <GeometryPath name="geometrypath">
          <PathPointSet><objects>
            <PathPoint name="p1"><socket_parent_frame>/ground</socket_parent_frame><location>0 1.1 0</location></PathPoint>
            <PathPoint name="p2"><socket_parent_frame>/bodyset/{body}</socket_parent_frame><location>0 -0.2 0</location></PathPoint>
          </objects></PathPointSet>
        </GeometryPath>
      </PathActuator>
    </objects></ForceSet>
  </Model>
</OpenSimDocument>
"""


def write(tmp_path, text, name="model.osim"):
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def model_text(joint="PinJoint", body="thigh", wrap=""):
    return MINIMAL.format(joint=joint, body=body, wrap=wrap)


def check(exc: InputError, path, *fragments):
    msg = str(exc)
    assert "\n" not in msg
    assert str(path) in msg, msg
    for frag in fragments:
        assert re.search(frag, msg), f"{frag!r} not in {msg!r}"


def test_minimal_model_is_valid(tmp_path):
    # the fixture itself is a good model: the failures below come from the one change each makes
    model = load_model(write(tmp_path, model_text()))
    assert model.coordinate_names == ("hip_flexion",)
    assert model.joints[0].kind == "PinJoint"


def test_missing_file(tmp_path):
    path = tmp_path / "nope.osim"
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "not found", "check the path")


def test_empty_file(tmp_path):
    path = write(tmp_path, "   \n")
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "empty")


def test_binary_file(tmp_path):
    path = write(tmp_path, b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" * 10)
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "binary")


def test_truncated_xml(tmp_path):
    text = model_text()
    path = write(tmp_path, text[: len(text) // 2])
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "truncated", r"line \d+")


def test_not_an_opensim_document(tmp_path):
    path = write(tmp_path, "<?xml version='1.0'?><html><body>hi</body></html>")
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "not an OpenSim document", "/html")


def test_document_without_model(tmp_path):
    path = write(tmp_path, '<OpenSimDocument Version="40000"><Storage/></OpenSimDocument>')
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "no <Model>")


def test_unknown_joint_type(tmp_path):
    path = write(tmp_path, model_text(joint="FooJoint"))
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, re.escape("/OpenSimDocument/Model[@name='mini']/JointSet[@name='jointset']/objects/"
                                     "FooJoint[@name='hip']"), "unknown joint type", "CustomJoint")


def test_path_point_on_missing_body(tmp_path):
    path = write(tmp_path, model_text(body="shank"))
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, r"PathPoint\[@name='p2'\]/socket_parent_frame", "shank", "existing body")


def test_negative_wrap_radius(tmp_path):
    wrap = ('<WrapCylinder name="cyl"><radius>-0.02</radius><length>0.1</length>'
            '<quadrant>x</quadrant></WrapCylinder>')
    path = write(tmp_path, model_text(wrap=wrap))
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, r"WrapCylinder\[@name='cyl'\]/radius", "positive", "-0.02")


def test_bad_quadrant_and_number(tmp_path):
    wrap = '<WrapSphere name="s"><radius>0.02</radius><quadrant>q</quadrant></WrapSphere>'
    with pytest.raises(InputError, match="quadrant"):
        load_model(write(tmp_path, model_text(wrap=wrap)))
    text = model_text().replace("<range>-1 1</range>", "<range>-1 abc</range>")
    with pytest.raises(InputError, match=r"Coordinate\[@name='hip_flexion'\]/range"):
        load_model(write(tmp_path, text, "b.osim"))


def test_billion_laughs_is_refused(tmp_path):
    bomb = ('<?xml version="1.0"?>\n<!DOCTYPE lolz [\n <!ENTITY lol "lol">\n'
            + "".join(f' <!ENTITY lol{i} "{("&lol" + (str(i - 1) if i > 1 else "") + ";") * 10}">\n'
                      for i in range(1, 10))
            + ']>\n<OpenSimDocument Version="40000"><Model name="&lol9;"/></OpenSimDocument>\n')
    path = write(tmp_path, bomb)
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "entities", "DOCTYPE")


def test_external_entity_is_refused(tmp_path):
    xxe = ('<?xml version="1.0"?><!DOCTYPE m [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
           '<OpenSimDocument Version="40000"><Model name="&x;"/></OpenSimDocument>')
    path = write(tmp_path, xxe)
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "entities")


def test_wrap_object_reference_must_exist(tmp_path):
    text = model_text().replace("</PathPointSet>", "</PathPointSet><PathWrapSet><objects><PathWrap name='w'>"
                                "<wrap_object>ghost</wrap_object></PathWrap></objects></PathWrapSet>")
    path = write(tmp_path, text)
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "ghost", r"PathWrap\[@name='w'\]/wrap_object")


def test_unsupported_function(tmp_path):
    text = model_text(joint="CustomJoint").replace(
        "</frames>", "</frames><SpatialTransform><TransformAxis name='rotation1'><coordinates>hip_flexion"
        "</coordinates><axis>0 0 1</axis><GCVSpline name='function'/></TransformAxis></SpatialTransform>")
    path = write(tmp_path, text)
    with pytest.raises(InputError) as err:
        load_model(path)
    check(err.value, path, "GCVSpline", "not supported", "SimmSpline")
