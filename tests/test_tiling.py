"""Searching a frame's overlapping windows as well as the whole frame, and merging what each pass finds."""

import itertools

import numpy as np
import pytest

from renderloop.perception.detector import INPUT_SIZE, Detection, Detector
from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.perception.tiling import cut_by_window, parse_layouts, windows


def test_a_paper_frame_gets_four_overlapping_windows_on_its_corners() -> None:
    parts = windows(640, 480, 2, 2, 320)
    assert parts == [(0, 0, 352, 264), (288, 0, 640, 264), (0, 216, 352, 480), (288, 216, 640, 480)]
    covered = np.zeros((480, 640), dtype=bool)
    for x0, y0, x1, y1 in parts:
        covered[y0:y1, x0:x1] = True
    assert covered.all()


@pytest.mark.parametrize(("columns", "rows"), [(2, 2), (3, 2), (5, 5), (1, 3)])
def test_windows_cover_the_frame_with_shared_strips(columns: int, rows: int) -> None:
    parts = windows(4000, 3000, columns, rows, 320)
    assert len(parts) == columns * rows
    covered = np.zeros((300, 400), dtype=bool)  # the frame at a tenth
    for x0, y0, x1, y1 in parts:
        covered[y0 // 10:y1 // 10, x0 // 10:x1 // 10] = True
    assert covered.all()
    for edges in ({(x0, x1) for x0, _, x1, _ in parts}, {(y0, y1) for _, y0, _, y1 in parts}):
        assert all(right[0] < left[1] for left, right in itertools.pairwise(sorted(edges)))  # neighbours overlap


def test_a_paper_frame_gets_3x2_windows_but_not_the_blurred_3x3_ones() -> None:
    parts = windows(640, 480, 3, 2, 320)
    assert {(x1 - x0, y1 - y0) for x0, y0, x1, y1 in parts} == {(235, 264)}  # enlarged 1.36 and 1.21 times
    assert [x0 for x0, _, _, _ in parts[:3]] == [0, 202, 405]
    assert windows(640, 480, 3, 3, 320) == []  # 176 px high: enlarged 1.82 times


def test_no_windows_for_one_cell_or_when_the_input_would_enlarge_them_more_than_allowed() -> None:
    assert windows(640, 480, 1, 1, 320) == []
    assert windows(320, 240, 2, 2, 320) == []  # the demo's frames: 176x132 windows, enlarged 2.4 times
    assert windows(320, 240, 2, 2, 384) == []
    # the greenhouse preset allows 3: its 320x240 frames get the four windows, enlarged 2.9 times at 384 px
    assert windows(320, 240, 2, 2, 384, max_enlargement=3.0) == [(0, 0, 176, 132), (144, 0, 320, 132),
                                                                   (0, 108, 176, 240), (144, 108, 320, 240)]
    assert windows(320, 240, 2, 2, 400, max_enlargement=3.0) == []  # 400 / 132 = 3.03


def test_window_layouts_parse_and_bad_ones_are_refused() -> None:
    assert parse_layouts("2x2, 3x2") == [(2, 2), (3, 2)]
    assert parse_layouts("None") == []
    for text in ("2", "2x9", "3x2,", "axb", ""):
        with pytest.raises(UserError, match="--windows"):
            parse_layouts(text)


def test_a_box_on_an_inner_window_edge_is_cut_and_one_on_the_frame_border_is_not() -> None:
    right_window = (288, 0, 640, 264)
    assert cut_by_window((289.0, 50.0, 320.0, 80.0), right_window, 640, 480)  # on x = 288, inside the frame
    assert cut_by_window((400.0, 240.0, 430.0, 263.0), right_window, 640, 480)  # on y = 264
    assert not cut_by_window((600.0, 0.0, 640.0, 30.0), right_window, 640, 480)  # the frame's own corner
    assert not cut_by_window((400.0, 50.0, 430.0, 80.0), right_window, 640, 480)


class ScriptedNetwork(Detector):
    """A detector whose network answers by the size of the image it is given: the whole frame or a window.
    It tests the tiling and merging around the network, not the network."""

    def __init__(self, answers: dict[tuple[int, int], list[list[Detection]]]) -> None:
        self.answers = {size: list(replies) for size, replies in answers.items()}
        self.input_size = INPUT_SIZE  # windows are laid out for a model of the trained input

    def _detect_once(self, rgb: np.ndarray, score_threshold: float) -> list[Detection]:
        return [d for d in self.answers[rgb.shape[:2]].pop(0) if d.score >= score_threshold]


def test_windows_add_small_fruit_drop_cut_boxes_and_fuse_what_two_passes_saw() -> None:
    whole = [Detection((100.0, 100.0, 160.0, 170.0), 0.9, "ripe"), Detection((500.0, 400.0, 540.0, 440.0), 0.3, "ripe")]
    network = ScriptedNetwork({
        (480, 640): [whole],
        (264, 352): [
            [Detection((102.0, 101.0, 161.0, 168.0), 0.7, "ripe"),  # the whole frame's fruit again: fused
             Detection((30.0, 40.0, 44.0, 56.0), 0.6, "ripe")],  # a small fruit only this window finds
            [Detection((0.5, 10.0, 20.0, 40.0), 0.8, "ripe")],  # cut by the window's left edge (x = 288): dropped
            [Detection((200.0, 100.0, 215.0, 118.0), 0.3, "unripe")],  # under the threshold, alone
            [Detection((100.0, 100.0, 120.0, 124.0), 0.55, "unripe"),
             Detection((212.0, 184.0, 252.0, 224.0), 0.4, "ripe")],  # the whole frame's 0.3 box: together 0.58
        ],
    })
    found = network.detect(np.zeros((480, 640, 3), dtype=np.uint8), 0.5, [(2, 2)])
    assert [(d.bbox, round(d.score, 6), d.label) for d in found] == [
        ((100.0, 100.0, 160.0, 170.0), 0.97, "ripe"),  # 1 - (1 - 0.9)(1 - 0.7)
        ((30.0, 40.0, 44.0, 56.0), 0.6, "ripe"),
        ((500.0, 400.0, 540.0, 440.0), 0.58, "ripe"),  # shifted by the window's corner (288, 216); 1 - 0.7 * 0.6
        ((388.0, 316.0, 408.0, 340.0), 0.55, "unripe"),
    ]


def test_no_layouts_is_the_whole_frame_alone() -> None:
    whole = [Detection((1.0, 2.0, 30.0, 40.0), 0.9, "ripe")]
    network = ScriptedNetwork({(480, 640): [whole]})
    assert network.detect(np.zeros((480, 640, 3), dtype=np.uint8), 0.5, []) == whole


class BrightPatchNetwork(Detector):
    """A 'network' that boxes the bright pixels of whatever view it is given, at score 0.5: where a pass
    puts the box depends on the pixels it was shown, so the mirroring is tested, not assumed."""

    def __init__(self) -> None:
        self.passes = 0
        self.input_size = INPUT_SIZE

    def _detect_once(self, rgb: np.ndarray, score_threshold: float) -> list[Detection]:
        self.passes += 1
        rows, cols = np.nonzero(rgb[:, :, 0])
        if len(rows) == 0:
            return []
        return [Detection((float(cols.min()), float(rows.min()), float(cols.max() + 1), float(rows.max() + 1)), 0.5, "ripe")]


@pytest.mark.parametrize(("layouts", "passes", "passes_holding_the_patch"), [([], 2, 2), ([(2, 2)], 6, 3), ([(2, 2), (3, 2)], 12, 4)])
def test_the_mirrored_pass_comes_back_unmirrored_and_fuses(layouts: list, passes: int, passes_holding_the_patch: int) -> None:
    frame = np.zeros((480, 640, 3), dtype=np.uint8)
    frame[60:100, 100:141] = 255  # off-centre: a box left un-mirrored would land at x 499-540
    network = BrightPatchNetwork()
    found = network.detect(frame, 0.5, layouts, mirror=True)
    assert network.passes == passes
    assert [(d.bbox, d.score) for d in found] == [((100.0, 60.0, 141.0, 100.0), pytest.approx(1 - 0.5 ** passes_holding_the_patch))]


def test_the_settings_window_enlargement_decides_whether_a_small_frame_is_searched_in_windows() -> None:
    frame = np.zeros((240, 320, 3), dtype=np.uint8)  # 2x2 windows of 176x132: enlarged 2.4 times at 320 px
    for enlargement, passes in ((1.5, 2), (3.0, 6)):
        network = BrightPatchNetwork()
        network.search(frame, Config().override({"detector": {"max_window_enlargement": enlargement}}).detector)
        assert network.passes == passes  # the frame, its mirror, and the windows only where allowed
