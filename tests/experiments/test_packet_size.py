"""Experiment 1 (paper Fig. 10): packet sizes measured on a short run of the scenario."""

from __future__ import annotations

import itertools
import math
from functools import cache
from pathlib import Path

import pytest
from support.rsp_models import robot_model

from rcmlconf.experiments import packet_size as ps
from rcmlconf.experiments.plots import packet_size_figure
from rcmlconf.rsp.codec import Encryption

PNG = b"\x89PNG\r\n\x1a\n"
DURATION = 3.0


@cache
def run(encryption: Encryption = Encryption.NONE, seed: int = 0) -> ps.PacketSizeRun:
    return ps.run_packet_size(robot_model(), duration=DURATION, seed=seed, encryption=encryption)


def motion_only_size() -> int:
    """Header, Device Map and the payloads of the lips and both arms, from the model alone."""
    model = robot_model()
    payloads = sum(
        f.type.max_encoded_size
        for name in ("lip", "leftArm", "rightArm")
        for f in model.by_name[name].fields
    )
    return 20 + math.ceil(len(model.devices) / 8) + payloads


def test_motion_only_downlinks_are_header_map_and_motion_payloads() -> None:
    plain = run()
    assert motion_only_size() == 29
    assert plain.sizes_in(ps.MOTION) == {29: plain.kinds.count(ps.MOTION)}
    assert plain.expected_motion_size == 29


def test_music_downlinks_are_1992_bytes_without_encryption() -> None:
    assert run().sizes_in(ps.MUSIC) == {1992: run().kinds.count(ps.MUSIC)}


def test_encryption_adds_the_tag_to_every_downlink() -> None:
    sealed = run(Encryption.AES_256_GCM)
    assert set(sealed.sizes_in(ps.MOTION)) == {29 + 16}
    assert set(sealed.sizes_in(ps.MUSIC)) == {1992 + 16}
    assert sealed.times == run().times


def test_the_saving_lies_between_its_bounds() -> None:
    """Against packets as large as the largest sent, only motion-only packets save, each
    1 - A/B of one: 0 (all music) <= saving <= 1 - A/B (no music), and exactly share_A x that."""
    plain = run()
    a, b = 29, 1992
    share_a = plain.kinds.count(ps.MOTION) / len(plain.kinds)
    saving = plain.saving(plain.largest)
    assert plain.largest == b
    assert 0 < saving < 1 - a / b
    assert saving == pytest.approx(share_a * (1 - a / b), abs=1e-12)
    assert saving < plain.saving(plain.model_largest) < 1
    assert plain.model_largest == 4060


def test_the_schedule_has_the_papers_share_of_music() -> None:
    assert round(ps.PAPER_MUSIC_SHARE, 4) == 0.6068
    sections = ps.schedule(120.0)
    assert [s.kind for s in sections] == list("ABABABA")
    assert sections[0].start == 0
    assert sections[-1].end == pytest.approx(120.0)
    assert all(x.end == pytest.approx(y.start) for x, y in itertools.pairwise(sections))
    music = sum(s.end - s.start for s in sections if s.kind == ps.MUSIC)
    assert music / 120 == pytest.approx(ps.PAPER_MUSIC_SHARE, abs=0.02 / 120)


def test_every_period_sends_one_downlink_and_nothing_else() -> None:
    plain = run()
    assert len(plain.sizes) == round(DURATION / 0.02)
    assert plain.others == {}  # no keep-alives, ACKs or PERIODs
    assert plain.fragments_played == plain.fragments_sent == plain.kinds.count(ps.MUSIC)
    assert plain.fragment_gaps == 0


def test_the_same_seed_gives_the_same_run() -> None:
    again = ps.run_packet_size(robot_model(), duration=DURATION, seed=0)
    assert (again.times, again.sizes) == (run().times, run().sizes)


def test_the_figure_and_report(tmp_path: Path) -> None:
    runs = [run(), run(Encryption.AES_256_GCM)]
    out = packet_size_figure(runs, tmp_path / "fig10.png")
    assert out.read_bytes().startswith(PNG)
    text = ps.report(runs, "fig10.png")
    assert "| section A (motion only) | 34 B | 29 B | 45 B |" in text
    assert "| section B (motion + music) | 1,992 B | 1,992 B | 2,008 B |" in text
