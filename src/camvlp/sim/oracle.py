"""How well a rendered lamp's ID could be told at all: the renderer's own model as the oracle.

A decoder sees a lamp's stripes through what it assumes of the lamp (a disc, a profile across
it, a sensor model).  To tell a decoder's limits from the photo's, :func:`id_separation`
redraws the lamp with every other ID of the map, at every phase, with all else in the photo
known (the lamp's disc, hot core and halo, its neighbours' light, the clipping, the noise),
and gives the decimal log likelihood ratio of the photo as drawn against the best of them.
Below a decoder's margin (``camvlp.pipeline.decode.model_choice.MIN_MARGIN``) no decoder can name
the ID at that safety; far above it, the photo holds the ID and a decoder that misses it
leaves something out.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from camvlp.model.fixtures import FixtureMap
from camvlp.sim.render import LightPatch, Render, light_patches
from camvlp.sim.scene import id_waveform
from camvlp.sim.sensor import develops

__all__ = ["id_separation"]


def id_separation(
    photo: Render, fixture_map: FixtureMap, index: int, max_columns: int = 200
) -> tuple[float, int] | None:
    """The decimal log likelihood ratio by which lamp ``index`` of a render is told from the
    map's other IDs, and the ID it is told from least.

    Each other ID is drawn in the lamp's place at phases 1/4 chip apart, and around the
    three best of them 1/32 chip apart; the photo's noise-free light (its lamps' light plus
    the ambient, clipped at full scale) is compared with each, pixel by pixel and channel by
    channel, over the lamp's box (its disc and glow), in units of the noise: the sensor's
    shot and read noise and the 8-bit steps.  JPEG's error is left out, so the figure is that
    of the stored levels before compression.  The lights of the render's ``data_lights``
    send no ID, so their IDs are no candidates.

    Parameters
    ----------
    photo : Render
        The render (its camera, pose and resolved settings are used; its image is not).
    fixture_map : FixtureMap
        The map it was rendered from.
    index : int
        The lamp's index in the map.
    max_columns : int
        At most this many of the box's columns (across the readout: every ``stride``-th)
        are compared and the sum scaled by the stride; with a readout along columns, rows.

    Returns
    -------
    (float, int) or None
        The smallest ratio (decimal log) and its ID; None when the render used a camera's
        processing beyond the plain sensor (mosaic, tone curve, sharpening, vignetting, black
        point: not redrawn here), when the lamp was not drawn or sends data, or when the map
        has no other ID.
    """
    s = photo.settings
    if develops(s) or photo.camera is None:
        return None
    lights = light_patches(photo.camera, fixture_map, photo.pose, s)
    lamp = next((light for light in lights if light.index == index), None)
    others = [
        f for k, f in enumerate(fixture_map.fixtures) if k != index and f.id not in s.data_lights
    ]
    if lamp is None or not others or fixture_map.fixtures[index].id in s.data_lights:
        return None
    take, stride = _across(lamp, s, max_columns)
    rest = _the_rest(lights, lamp, s, take)
    truth = np.clip(rest + lamp.light(s, take), 0.0, 1.0)
    var = truth / np.float32(s.full_well_e) + np.float32(float(s.read_noise) ** 2 + 1 / 255**2 / 12)
    scale = stride / 2.0 / math.log(10)

    seps = []
    for other in others:  # its waveform (chips, or a frequency's period) at each phase
        chips, chip_s = id_waveform(fixture_map, other, s.chip_rate_hz)
        period = chips.size * chip_s
        wave = dict(chips=chips, chip_s=chip_s)
        wave["smooth_s"] = s.soft * (period if fixture_map.mode == "frequency" else chip_s)

        def ratio(phase: float, wave=wave, period=period) -> float:
            drawn = dataclasses.replace(lamp, phase_s=phase % period, **wave).light(s, take)
            alt = np.clip(rest + drawn, 0.0, 1.0)
            alt -= truth
            return scale * float(np.sum(alt * alt / var))

        coarse = np.arange(0.0, period, chip_s / 4)
        costs = np.array([ratio(ph) for ph in coarse])
        best = float(costs.min())
        for ph in coarse[np.argsort(costs)[:3]]:
            best = min(best, *(ratio(q) for q in ph + chip_s * np.arange(-8, 9) / 32.0))
        seps.append((best, other.id))
    return min(seps)


def _across(lamp: LightPatch, s, max_columns: int) -> tuple[tuple, int]:
    """The index into ``lamp``'s box of every ``stride``-th line across the readout (columns
    for a readout along rows, rows along columns; at most ``max_columns``), and the stride."""
    u0, u1, v0, v1 = lamp.box
    rows = s.readout.by_rows
    stride = max(1, -(-((u1 - u0) if rows else (v1 - v0)) // max_columns))
    lines = np.arange(0, (u1 - u0) if rows else (v1 - v0), stride)
    return ((slice(None), lines) if rows else (lines, slice(None))), stride


def _the_rest(lights: list, lamp: LightPatch, s, take: tuple) -> np.ndarray:
    """The light of the ambient and of every lamp but ``lamp`` over ``take`` of ``lamp``'s
    box (:func:`_across`), float32, full scale."""
    u0, u1, v0, v1 = lamp.box
    rest = np.full((v1 - v0, u1 - u0, 3), s.ambient, np.float32)
    for light in lights:
        if light is lamp:
            continue
        a0, a1, b0, b1 = light.box
        y0, y1, x0, x1 = max(b0, v0), min(b1, v1), max(a0, u0), min(a1, u1)
        if y0 < y1 and x0 < x1:
            part = light.light(s)[y0 - b0 : y1 - b0, x0 - a0 : x1 - a0]
            rest[y0 - v0 : y1 - v0, x0 - u0 : x1 - u0] += part
    return rest[take]
