"""tracker.video.area_shrink.shrink: INTER_AREA's averages, faster, for any ratio."""
import cv2
import numpy as np
import pytest

from tracker.video.area_shrink import shrink


def _scene(height: int, width: int) -> np.ndarray:
    """A smooth scene with a few sharp edges (BGR uint8)."""
    y, x = np.mgrid[0:height, 0:width]
    image = np.stack([(x * 255 // width), (y * 255 // height), ((x + y) % 256)], axis=2)
    image[height // 3: height // 2, width // 4: width // 3] = 250          # a bright box
    return image.astype(np.uint8)


def test_halvings_give_inter_area_exactly_or_within_rounding():
    image = _scene(480, 640)
    np.testing.assert_array_equal(shrink(image, (320, 240)),       # one halving: the same
                                  cv2.resize(image, (320, 240), interpolation=cv2.INTER_AREA))
    twice = shrink(image, (160, 120)).astype(int)                   # rounded in between
    assert np.abs(twice - cv2.resize(image, (160, 120), interpolation=cv2.INTER_AREA)).max() <= 1


@pytest.mark.parametrize("shape, size", [((1080, 1920), (320, 180)), ((1920, 1080), (320, 569)),
                                         ((721, 1283), (320, 180))])
def test_other_ratios_give_inter_areas_averages_up_to_edges(shape, size):
    image = _scene(*shape)
    out = shrink(image, size)
    ref = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    assert out.shape == ref.shape and out.dtype == np.uint8
    diff = np.abs(out.astype(int) - ref)
    assert diff.mean() < 1.5                      # the same picture: only edges move a little
    assert np.percentile(diff, 99) <= 12


def test_the_target_size_and_grey_images():
    grey = _scene(1080, 1920)[..., 0]
    assert shrink(grey, (320, 180)).shape == (180, 320)
    same = _scene(240, 320)
    assert shrink(same, (320, 240)) is same
