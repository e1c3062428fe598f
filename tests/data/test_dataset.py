"""ClipDataset windows, clip-start padding, resize/crop intrinsics, ground truth, collate."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch
from synthetic_clips import FRAME_NS, HEIGHT, T_LANE_CAM, WIDTH, K, build_store

from lanelab.data.collate import collate_samples
from lanelab.data.dataset import ClipDataset
from lanelab.data.frame_index import SampleKey
from lanelab.data.targets import LaneTargets
from lanelab.data.transforms import ResizeCrop
from lanelab.geometry import project_lane_points

MEAN, STD = (0.5, 0.4, 0.3), (0.2, 0.25, 0.3)
TARGETS = LaneTargets(np.linspace(3.0, 63.0, 31))
NO_RESIZE = ResizeCrop(HEIGHT, WIDTH)


def make_dataset(store, num_frames=4, resize=NO_RESIZE, split="train"):
    return ClipDataset(store, split, num_frames=num_frames, resize=resize, targets=TARGETS, mean=MEAN, std=STD)


def pixel(sample, frame: int) -> np.ndarray:
    """RGB uint8 at (0, 0) of a frame of a sample, normalisation undone."""
    rgb = sample["images"][frame, :, 0, 0] * torch.tensor(STD) + torch.tensor(MEAN)
    return (rgb * 255).round().to(torch.uint8).numpy()


def test_window_is_consecutive_frames_of_one_clip(tmp_path):
    dataset = make_dataset(build_store(tmp_path, {"train": [6, 9]}))
    assert len(dataset) == 15
    sample = dataset[6 + 7]  # clip 1, position 7
    assert sample["clip_id"] == "clip01"
    assert sample["frame_index"].tolist() == [4, 5, 6, 7]
    assert sample["valid"].all() and not sample["reset"] and not sample["padding"]
    np.testing.assert_array_equal(np.diff(sample["timestamp_ns"].numpy()), FRAME_NS)
    for f, position in enumerate([4, 5, 6, 7]):  # the pixels are those of the right frames
        assert pixel(sample, f).tolist()[:2] == [10 * position + 1, 1]
    assert sample["T_world_lane"][:, 1, 3].tolist() == [4.0, 5.0, 6.0, 7.0]
    assert sample["T_world_lane"].dtype == torch.float64
    torch.testing.assert_close(sample["T_lane_cam"], torch.from_numpy(T_LANE_CAM).float().expand(4, 4, 4))
    assert sample["tags"] == {"weather": "sun", "clip": "1"}


def test_clip_start_is_padded_with_the_first_frame_and_masked(tmp_path):
    dataset = make_dataset(build_store(tmp_path, {"train": [6, 9]}))
    sample = dataset[6 + 1]  # second frame of clip 1
    assert sample["valid"].tolist() == [False, False, True, True]
    assert sample["frame_index"].tolist() == [0, 0, 0, 1]
    torch.testing.assert_close(sample["images"][0], sample["images"][2])
    assert dataset[6]["reset"] and not dataset[7]["reset"]  # an int key resets at clip starts


def test_sampler_keys_choose_the_frames(tmp_path):
    dataset = make_dataset(build_store(tmp_path, {"train": [12]}))
    sample = dataset[SampleKey(10, (7, 2, 0), reset=True, padding=True)]
    assert sample["frame_index"].tolist() == [3, 8, 10]
    assert sample["images"].shape == (3, 3, HEIGHT, WIDTH)
    assert sample["padding"] and sample["reset"]
    assert dataset[SampleKey(1, (3, 0), False)]["valid"].tolist() == [False, True]


def test_sample_layout_and_ground_truth(tmp_path):
    dataset = make_dataset(build_store(tmp_path, {"train": [5]}, label_every=2))
    sample = dataset[4]
    assert sample["images"].shape == (4, 3, HEIGHT, WIDTH) and sample["images"].dtype == torch.float32
    assert sample["K"].shape == (4, 3, 3) and sample["T_world_lane"].shape == (4, 4, 4)
    assert sample["labeled"].tolist() == [False, True, False, True]
    assert sample["gt_x"].shape == (2, 31)
    # Lanes at x = -/+1.75 m from y = 0 to 60 m: visible at the 29 grid y 3, 5, ..., 59.
    torch.testing.assert_close(sample["gt_x"][:, 0], torch.tensor([-1.75, 1.75]))
    assert sample["gt_vis"].sum(1).tolist() == [29.0, 29.0]
    torch.testing.assert_close(sample["gt_y"], torch.from_numpy(TARGETS.y).float())
    assert dataset[3]["gt_x"].shape == (0, 31)  # an unlabeled current frame has no lanes


def test_images_are_normalised(tmp_path):
    sample = make_dataset(build_store(tmp_path, {"train": [2]}))[1]
    expected = (128 / 255 - torch.tensor(MEAN)) / torch.tensor(STD)
    torch.testing.assert_close(sample["images"][:, :, 5, 5], expected.expand(4, 3))


# --- resize / crop -------------------------------------------------------------------------

def test_resize_crop_intrinsics_are_exact():
    resize = ResizeCrop(90, 160, crop=(100, 40, 180, 320))
    K_new = resize.intrinsics(K, 480, 640)
    points = torch.tensor([[1.0, 20.0, 0.0], [-3.0, 35.0, 0.5], [0.2, 8.0, 0.0]], dtype=torch.float64)
    uv, _, _ = project_lane_points(points, torch.from_numpy(K), torch.from_numpy(T_LANE_CAM))
    uv_new, _, _ = project_lane_points(points, torch.from_numpy(K_new), torch.from_numpy(T_LANE_CAM))
    expected = (uv - torch.tensor([40.0, 100.0], dtype=torch.float64)) * torch.tensor([0.5, 0.5], dtype=torch.float64)
    torch.testing.assert_close(uv_new, expected)


@pytest.mark.parametrize("resize", [
    ResizeCrop(120, 160),  # shrink (area)
    ResizeCrop(200, 240, crop=(100, 100, 200, 320)),  # crop, then scale x 3/4 (area)
    ResizeCrop(300, 400, crop=(150, 200, 150, 200)),  # crop, then enlarge x 2 (bilinear)
])
def test_a_projected_point_lands_on_the_same_image_content(resize):
    """Draw a blob where a 3D point projects, resize / crop, find it where K' projects it."""
    point = torch.tensor([[0.8, 12.0, 0.0]], dtype=torch.float64)
    source = np.zeros((480, 640, 3), np.uint8)
    uv, _, _ = project_lane_points(point, torch.from_numpy(K * [[8], [8], [1]]), torch.from_numpy(T_LANE_CAM))
    u, v = uv[0].tolist()
    # Anti-aliased disc centred on (u, v) in the pixel-corner convention (cv2 centres are at +0.5).
    shift = 4
    cv2.circle(source, (round((u - 0.5) * 2**shift), round((v - 0.5) * 2**shift)), 12 * 2**shift,
               (255, 255, 255), -1, cv2.LINE_AA, shift)
    image, K_new = resize(source, K * [[8], [8], [1]])
    assert image.shape == (resize.height, resize.width, 3)

    expected, _, _ = project_lane_points(point, torch.from_numpy(K_new), torch.from_numpy(T_LANE_CAM))
    weights = image[..., 0].astype(np.float64)
    rows, cols = np.mgrid[: image.shape[0], : image.shape[1]]
    centroid = np.array([(weights * (cols + 0.5)).sum(), (weights * (rows + 0.5)).sum()]) / weights.sum()
    np.testing.assert_allclose(centroid, expected[0].numpy(), atol=0.05)


def test_dataset_intrinsics_follow_the_resize(tmp_path):
    resize = ResizeCrop(24, 16, crop=(8, 16, 24, 32))
    sample = make_dataset(build_store(tmp_path, {"train": [3]}), resize=resize)[2]
    assert sample["images"].shape == (4, 3, 24, 16)
    torch.testing.assert_close(sample["K"][-1], torch.from_numpy(resize.intrinsics(K, HEIGHT, WIDTH)).float())


def test_a_crop_outside_the_image_is_refused():
    with pytest.raises(ValueError, match="does not fit"):
        ResizeCrop(10, 10, crop=(0, 0, 50, 50))(np.zeros((40, 40, 3), np.uint8), K)


# --- collate -------------------------------------------------------------------------------

def test_collate_stacks_and_pads_lanes(tmp_path):
    dataset = make_dataset(build_store(tmp_path, {"train": [4]}, label_every=2))
    batch = collate_samples([dataset[2], dataset[3]], max_lanes=5)  # 2 lanes, then none
    assert batch["images"].shape == (2, 4, 3, HEIGHT, WIDTH)
    assert batch["valid"].shape == (2, 4) and batch["reset"].shape == (2,)
    assert batch["gt_x"].shape == (2, 5, 31)
    assert batch["gt_mask"].tolist() == [[True, True, False, False, False], [False] * 5]
    assert batch["gt_category"][0].tolist() == [2, 2, 0, 0, 0]
    assert batch["clip_id"] == ["clip00", "clip00"] and len(batch["tags"]) == 2
    with pytest.raises(ValueError, match="max_lanes=1"):
        collate_samples([dataset[2]], max_lanes=1)


def test_a_flipped_sample_is_the_mirror_image_with_its_lanes_and_cameras_mirrored(tmp_path):
    """A mirrored sample: images flipped left to right, lanes at -x with left and right categories
    swapped, and cameras and poses reflected so that a lane point still projects onto the same
    image content: pixel column u of the original becomes W - u."""
    store = build_store(tmp_path, {"train": [5]})
    dataset = make_dataset(store, num_frames=2)
    plain, mirrored = (dataset[SampleKey(3, (1, 0), True, False, flip)] for flip in (False, True))
    torch.testing.assert_close(mirrored["images"], plain["images"].flip(-1))
    torch.testing.assert_close(mirrored["gt_x"], -plain["gt_x"])
    point = torch.stack([plain["gt_x"][0, 5], plain["gt_y"][5], plain["gt_z"][0, 5]]).double()[None]
    uv, _, _ = project_lane_points(point, plain["K"][-1].double(), plain["T_lane_cam"][-1].double())
    flipped = point * torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64)
    uv_m, _, _ = project_lane_points(flipped, mirrored["K"][-1].double(), mirrored["T_lane_cam"][-1].double())
    torch.testing.assert_close(uv_m[0], torch.stack([WIDTH - uv[0, 0], uv[0, 1]]), rtol=0, atol=1e-4)
    # The ego motion between the two frames is the mirror image too: still straight ahead here.
    motion = torch.linalg.inv(mirrored["T_world_lane"][1]) @ mirrored["T_world_lane"][0]
    torch.testing.assert_close(motion, torch.linalg.inv(plain["T_world_lane"][1]) @ plain["T_world_lane"][0])


def test_mirrored_categories_swap_sides_and_keep_the_rest():
    from lanelab.data.mirror import mirror_categories

    assert mirror_categories(np.array([1, 5, 6, 11, 12, 20, 21, 8])).tolist() == [1, 6, 5, 12, 11, 21, 20, 8]
