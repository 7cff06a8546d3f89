"""Scenes: loading, validation messages, pose interpolation, footprint checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from multisonar.constants import speed_of_sound
from multisonar.scene import (MAX_ROBOT_SPEED, SCENE_DIR, Scene, SceneError, available_scenes, load_scene,
                              parse_scene)

SHIPPED = ["empty", "wall_1m", "corridor", "person_crossing"]


def scene(**doc) -> Scene:
    return parse_scene(doc, source="<test>")


def wall_doc(**wall):
    return {"walls": [wall]}


# ------------------------------------------------------------------ shipped scenes

@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenes_load(name):
    sc = load_scene(name)
    assert sc.name == name
    assert sc.layout.n == 24
    assert sc.description
    assert sc.speed_of_sound == pytest.approx(speed_of_sound(sc.temperature_c))
    t = np.linspace(0, sc.duration_s, 101)
    x, y, h = sc.pose(t)
    assert x.shape == y.shape == h.shape == t.shape
    vx, vy, _ = sc.velocity(t)
    assert np.all(np.hypot(vx, vy) <= MAX_ROBOT_SPEED + 1e-9)


def test_available_scenes_lists_shipped():
    assert set(SHIPPED) <= set(available_scenes())


def test_all_yaml_files_in_scene_dir_load():
    for p in SCENE_DIR.glob("*.yaml"):
        load_scene(p)


def test_empty_has_no_reflectors():
    sc = load_scene("empty")
    assert sc.n_reflectors == 0 and sc.reflector_names == ()
    assert sc.is_static


def test_wall_1m_geometry_and_orientation_parameter():
    sc = load_scene("wall_1m")
    assert sc.is_static and sc.wall_names == ("wall",)
    a, b = sc.walls[0]
    # the wall passes through the pivot at distance 1 m, bearing 7.5 deg, perpendicular to it
    u = np.array([math.cos(math.radians(7.5)), math.sin(math.radians(7.5))])
    assert np.dot(a, u) == pytest.approx(1.0) and np.dot(b, u) == pytest.approx(1.0)
    assert np.linalg.norm(b - a) == pytest.approx(3.0)
    sc2 = load_scene("wall_1m", orientation_deg=100.0)
    d = sc2.walls[0, 1] - sc2.walls[0, 0]
    assert math.degrees(math.atan2(d[1], d[0])) == pytest.approx(107.5)
    assert sc2.parameters["orientation_deg"] == 100.0


def test_corridor_drives_at_up_to_2_m_s_with_door_edge_and_walls():
    sc = load_scene("corridor")
    assert not sc.is_static
    v = np.hypot(*sc.velocity(np.linspace(0, sc.trajectory_t[-1], 1000))[:2])
    assert v.max() == pytest.approx(2.0)
    assert len(sc.wall_names) >= 4 and len(sc.point_names) >= 2 and len(sc.cylinder_names) >= 1
    assert sc.trajectory_t[-1] >= 2.0


def test_person_crossing_person_passes_between_robot_and_wall():
    sc = load_scene("person_crossing")
    assert len(sc.people) == 1
    wall_y = sc.walls[0, 0, 1]
    t = np.linspace(0, sc.duration_s, 400)
    p = sc.people_positions(t)[:, 0]
    x, y, _ = sc.pose(t)
    assert np.all((p[:, 1] > y) & (p[:, 1] < wall_y))
    # the person passes the robot (x order flips)
    assert (p[0, 0] - x[0]) * (p[-1, 0] - x[-1]) < 0


def test_overrides_seed_noise_and_model():
    sc = load_scene("wall_1m", seed=7, jitter_s=0.0, noise={"spurious_rate_hz": 0}, model={"second_order": False})
    assert sc.seed == 7 and sc.noise.jitter_s == 0 and sc.noise.spurious_rate_hz == 0
    assert sc.model.second_order is False


def test_unknown_override_lists_parameters():
    with pytest.raises(SceneError, match=r"unknown override.*orientation_deg"):
        load_scene("wall_1m", orientatoin_deg=3)


# ------------------------------------------------------------------ poses

def test_pose_interpolation_vectorised():
    sc = scene(trajectory=[{"t": 0, "x": 0, "y": 0, "heading_deg": 0},
                           {"t": 1, "x": 1, "y": 0, "heading_deg": 90},
                           {"t": 2, "x": 1, "y": 1.5}])
    x, y, h = sc.pose([-1.0, 0.0, 0.5, 1.0, 1.5, 2.0, 3.0])
    np.testing.assert_allclose(x, [0, 0, 0.5, 1, 1, 1, 1])
    np.testing.assert_allclose(y, [0, 0, 0, 0, 0.75, 1.5, 1.5])
    np.testing.assert_allclose(h, np.radians([0, 0, 45, 90, 90, 90, 90]))
    x2, _, _ = sc.pose(np.zeros((3, 4)))
    assert x2.shape == (3, 4)
    vx, vy, w = sc.velocity([0.5, 1.5, 5.0])
    np.testing.assert_allclose(vx, [1, 0, 0])
    np.testing.assert_allclose(vy, [0, 1.5, 0])
    np.testing.assert_allclose(w, [math.pi / 2, 0, 0])


def test_speed_waypoints_compute_times():
    sc = scene(trajectory=[{"x": 0, "y": 0}, {"speed": 2.0, "x": 3, "y": 4}, {"t": 10}])
    np.testing.assert_allclose(sc.trajectory_t, [0, 2.5, 10])
    np.testing.assert_allclose(sc.trajectory_pose[-1], [3, 4, 0])


def test_element_poses_follow_heading():
    sc = scene(trajectory=[{"t": 0, "x": 1, "y": 2, "heading_deg": 90}])
    pos, ax = sc.element_poses(0.0)
    np.testing.assert_allclose(pos[0], [1, 2.35], atol=1e-12)  # element 0 (robot +x) now points +y
    assert ax[0] == pytest.approx(math.pi / 2)
    pos1, ax1 = sc.element_poses(np.array([0.0, 0.0]), np.array([0, 6]))
    np.testing.assert_allclose(pos1, [[1, 2.35], [0.65, 2]], atol=1e-12)


def test_default_trajectory_is_static_origin():
    sc = scene()
    assert sc.is_static
    assert [float(v) for v in sc.pose(3.0)] == [0.0, 0.0, 0.0]


# ------------------------------------------------------------------ units and expressions

def test_units_and_expressions():
    sc = scene(parameters={"d": 2.0},
               trajectory=[{"t": 0, "heading_deg": "0.5 rad"}],
               walls=[{"name": "w", "a": ["d", "-1000 mm"], "b": ["d * 1", "100 cm"]}],
               cylinders=[{"center": ["d + 1", 0], "radius": "50 mm"}],
               noise={"jitter_s": "2 us", "spurious_rate_hz": "0.01 kHz"})
    assert sc.trajectory_pose[0, 2] == pytest.approx(0.5)
    np.testing.assert_allclose(sc.walls[0], [[2, -1], [2, 1]])
    assert sc.cylinder_radius[0] == pytest.approx(0.05)
    assert sc.noise.jitter_s == pytest.approx(2e-6) and sc.noise.spurious_rate_hz == pytest.approx(10)


def test_polyline_and_through_walls():
    sc = scene(walls=[{"name": "room", "polyline": [[2, -2], [2, 2], [-2, 2]]},
                      {"name": "t", "through": [0, -2], "direction_deg": 0, "length": 2}])
    assert sc.wall_names == ("room.0", "room.1", "t")
    np.testing.assert_allclose(sc.walls[2], [[-1, -2], [1, -2]], atol=1e-12)
    assert sc.reflector_index("room.1") == 1


# ------------------------------------------------------------------ validation errors

@pytest.mark.parametrize("doc, pattern", [
    ({"wals": []}, r"unknown key\(s\) \['wals'\]; allowed: \[.*'walls'"),
    (wall_doc(a=[1, 0], b=[1, 1], colour="red"), r"walls\[0\]: unknown key\(s\) \['colour'\]; allowed"),
    ({"cylinders": [{"center": [2, 0], "radius": "20 deg"}]}, r"cylinders\[0\]\.radius: wrong unit 'deg' in '20 deg': expected length"),
    ({"cylinders": [{"center": [2, 0], "radius": -0.1}]}, r"cylinders\[0\]\.radius: must be > 0, got -0.1"),
    ({"cylinders": [{"center": [2, 0], "radius": [1]}]}, r"cylinders\[0\]\.radius: expected a number"),
    ({"cylinders": [{"center": [2, 0], "radius": "0.1 furlong"}]}, r"unknown unit 'furlong'"),
    ({"cylinders": [{"center": 2, "radius": 0.1}]}, r"cylinders\[0\]\.center: expected a point \[x, y\]"),
    ({"cylinders": [{"radius": 0.1}]}, r"cylinders\[0\]: missing key\(s\) \['center'\]"),
    ({"trajectory": [{"t": 0, "heading": 90}]}, r"trajectory\[0\]: unknown key\(s\) \['heading'\]; allowed: .*heading_deg"),
    ({"trajectory": [{"t": 0, "x": 0}, {"t": 1, "x": 2.5}]}, r"trajectory\[1\]: robot speed 2.500 m/s .* exceeds .* 2.0 m/s"),
    ({"trajectory": [{"t": 0}, {"speed": 2.5, "x": 3}]}, r"robot speed 2.500 m/s"),
    ({"trajectory": [{"t": 1}, {"t": 1, "x": 1}]}, r"trajectory\[1\]\.t: times must increase"),
    ({"trajectory": [{"t": 0}, {"x": 1}]}, r"exactly one of 't' \(s\) or 'speed'"),
    ({"trajectory": []}, r"trajectory: needs at least one waypoint"),
    (wall_doc(a=[0.3, -1], b=[0.3, 1]), r"wall 'wall0' comes within 0.300 m .* inside the robot footprint"),
    ({"points": [{"at": [0.2, 0.1]}]}, r"point 'point0' comes within .* footprint"),
    ({"cylinders": [{"center": [0.6, 0], "radius": 0.3}]}, r"cylinder 'cylinder0' comes within .* footprint"),
    ({"walls": [{"a": [1, 0], "b": [1, 0]}]}, r"zero length"),
    ({"walls": [{"a": [1, 0], "b": [1, 1], "length": 2}]}, r"exactly one of"),
    ({"walls": [{"a": [1, 0], "b": [1, 1], "reflectivity": 1.5}]}, r"reflectivity: must be <= 1"),
    ({"points": [{"name": "x", "at": [2, 0]}, {"name": "x", "at": [3, 0]}]}, r"duplicate reflector name 'x'"),
    ({"points": [{"at": ["dist", 0]}]}, r"unknown name 'dist'"),
    ({"points": [{"at": ["__import__('os')", 0]}]}, r"unsupported syntax"),
    ({"temperature_c": 500}, r"temperature_c: must be <= 70"),
    ({"seed": -1}, r"seed: expected a non-negative integer"),
    ({"layout": "ring99"}, r"layout: layout 'ring99' not found"),
    ({"noise": {"jitter": 1e-6}}, r"noise: unknown key\(s\) \['jitter'\]; allowed: .*jitter_s"),
    ({"noise": {"threshold": 0}}, r"noise.threshold: must be > 0"),
    ({"noise": {"jitter_s": -1e-6}}, r"noise.jitter_s: must be >= 0"),
    ({"model": {"second_order": "yes"}}, r"model.second_order: expected true or false"),
    ({"parameters": {"sin": 1}}, r"parameters.sin"),
    ({"people": [{"path": [{"t": 0, "x": 2, "y": 0}, {"t": 1, "x": 7, "y": 0}]}]}, r"person speed 5.00 m/s"),
])
def test_validation_errors(doc, pattern):
    with pytest.raises(SceneError, match=pattern) as exc:
        parse_scene(doc, source="bad.yaml")
    assert str(exc.value).startswith("bad.yaml")


def test_moving_robot_hits_static_point_on_its_way():
    doc = {"trajectory": [{"t": 0, "x": 0, "y": 0}, {"t": 2, "x": 3, "y": 0}], "points": [{"name": "rod", "at": [1.5, 0.2]}]}
    with pytest.raises(SceneError, match=r"point 'rod' comes within 0.200 m"):
        parse_scene(doc)


def test_person_walking_into_robot_is_rejected_but_passing_is_fine():
    base = {"trajectory": [{"t": 0, "x": 0, "y": 0}, {"t": 2, "x": 2, "y": 0}]}
    # person walks against the robot in the same lane: they meet at x=2, t=1 (relative motion)
    bad = dict(base, people=[{"name": "bob", "path": [{"t": 0, "x": 4, "y": 0.1}, {"t": 2, "x": 0, "y": 0.1}]}])
    with pytest.raises(SceneError, match=r"person 'bob' comes within"):
        parse_scene(bad)
    ok = dict(base, people=[{"name": "bob", "path": [{"t": 0, "x": 4, "y": 1.0}, {"t": 2, "x": 0, "y": 1.0}]}])
    parse_scene(ok)


def test_missing_file_lists_known_scenes():
    with pytest.raises(SceneError, match=r"scene 'nope' not found.*known scenes: \[.*'wall_1m'"):
        load_scene("nope")


def test_bad_yaml_file(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("walls: [\n")
    with pytest.raises(SceneError, match=r"bad.yaml: not valid YAML"):
        load_scene(p)
    p.write_text(yaml.safe_dump({"walls": [{"a": [1, 0], "b": [1, 1], "oops": 1}]}))
    with pytest.raises(SceneError, match=r"bad.yaml: walls\[0\]: unknown key"):
        load_scene(p)


def test_scene_from_file_path(tmp_path):
    p = tmp_path / "mine.yaml"
    p.write_text(yaml.safe_dump({"walls": [{"name": "w", "a": [1, -1], "b": [1, 1]}], "seed": 5}))
    sc = load_scene(p)
    assert sc.name == "mine" and sc.seed == 5 and sc.wall_names == ("w",)
