"""The problem model (pipeline/problem.py, docs/architecture.md "The problem model"): every
image carries the key of its instant, the problem groups the images of all cameras by it,
each camera names the unknown X it determines, and a camera's motion capture may be absent."""

from __future__ import annotations

import typing
from dataclasses import replace

from multieye.io import load_rig
from multieye.pipeline import load_camera_data
from multieye.pipeline.camera_data import CameraData, instant_key
from multieye.pipeline.options import Options
from multieye.pipeline.problem import Instant, View, group_instants, make_problem
from pose_dataset import write_pose_dataset


def _problem(tmp_path):
    folder, _, _ = write_pose_dataset(tmp_path)
    rig = load_rig(folder / "rig.yaml")
    return make_problem(rig, load_camera_data(rig, processes=1), Options())


def test_every_image_has_its_instant_and_the_problem_groups_them(tmp_path):
    problem = _problem(tmp_path)
    for name, data in problem.cameras.items():
        assert [o.instant for o in data.observations] == [repr(float(o.stamp))
                                                          for o in data.observations]
        for k, o in enumerate(data.observations):
            assert View(name, k) in problem.instants[o.instant].views
    # the two cameras of this rig were recorded one after the other: no instant is shared
    assert sum(len(i.views) for i in problem.instants.values()) == 24
    assert all(len(i.views) == 1 for i in problem.instants.values())
    assert problem.unknown_x == {"cam0": "cam0", "cam1": "cam1"}


def test_images_of_two_cameras_at_one_instant_are_one_instant(tmp_path):
    cameras = _problem(tmp_path).cameras
    a, b = cameras["cam0"], cameras["cam1"]
    # cam1's images taken at cam0's stamps: the same instants
    moved = replace(b, observations=tuple(
        replace(o, stamp=p.stamp, instant=p.instant) for o, p in zip(b.observations,
                                                                    a.observations)))
    instants = group_instants({"cam0": a, "cam1": moved})
    assert len(instants) == 12
    first = instants[a.observations[0].instant]
    assert first == Instant(first.key, (View("cam0", 0), View("cam1", 0)))


def test_instant_key_by_name_is_the_stem(tmp_path):
    o = _problem(tmp_path).cameras["cam0"].observations[0]
    assert instant_key(replace(o, name="img12.png"), by_name=True) == "img12"
    assert instant_key(o, by_name=False) == repr(float(o.stamp))


def test_motion_capture_may_be_absent_in_the_model():
    hints = typing.get_type_hints(CameraData)
    assert type(None) in typing.get_args(hints["mocap"])
