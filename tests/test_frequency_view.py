"""A measured frequency response shows itself like every result: a one-line ``repr`` with
units, a card, strict-JSON ``to_dict()`` with unit-named keys and a Bode plot with the
coherence; the stroke check and the margins print one line too."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from servo_toolkit.identify import read_data
from servo_toolkit.identify.data import FrequencyData
from servo_toolkit.identify.frf import frf_csv
from servo_toolkit.loop.margins import Margins
from servo_toolkit.loop.stroke import StrokeCheck

from .figure_layout import layout_faults

#: a first-order lag at 20 Hz over 240 lines from 1 to 200 Hz, its coherence falling from
#: 0.99 to 0.45 (median 0.72; 155 lines below 0.8)
F = np.geomspace(1.0, 200.0, 240)
H = 1.0 / (1.0 + 1j * F / 20.0)
COHERENCE = np.linspace(0.99, 0.45, 240)


@pytest.fixture(scope="module")
def measured():
    return FrequencyData.from_complex(F, H, coherence=COHERENCE, averages=4, window="periodic",
                                      resolution=np.full(F.size, 1e-3))


@pytest.fixture
def from_file(measured, tmp_path):
    path = tmp_path / "stim.csv"
    path.write_text("# signal: motor_speed_rad_s\n" + frf_csv(measured))
    return read_data(path)


def test_repr_is_one_line_with_units(measured, from_file):
    text = repr(measured)
    assert text == "<FrequencyData: 240 lines 1-200 Hz, H1 periodic over 4 spectra, coherence 0.72 median>"
    assert f"{np.median(COHERENCE):.2f}" == "0.72"
    text = repr(from_file)
    assert "\n" not in text and "array" not in text
    assert text.startswith("<FrequencyData: 240 lines 1-200 Hz of motor_speed_rad_s, 4 spectra averaged")
    assert text.endswith(", from stim.csv>")


def test_to_dict_is_strict_json_with_unit_named_keys(measured, from_file):
    d = json.loads(json.dumps(measured.to_dict(), allow_nan=False))
    assert d["points"] == 240 and d["averages"] == 4 and d["window"] == "periodic" and d["source"] is None
    assert np.allclose(d["frequency_hz"], F) and np.allclose(d["coherence"], COHERENCE)
    assert np.allclose(d["gain_db"], 20 * np.log10(np.abs(H)))
    assert np.allclose(d["phase_deg"], np.degrees(np.angle(H)))
    # 1e-3 neper of resolution: 20 / ln 10 times it in dB, in degrees as radians
    assert np.allclose(d["resolution_db"], 1e-3 * 20 / math.log(10))
    assert np.allclose(d["resolution_deg"], math.degrees(1e-3))
    f = json.loads(json.dumps(from_file.to_dict(), allow_nan=False))
    assert f["signal"] == "motor_speed_rad_s" and f["source"].endswith("stim.csv") and f["window"] is None
    bare = FrequencyData(F[:3], np.array([0.0, -1.0, -2.0]), np.zeros(3), np.ones(3))
    b = json.loads(json.dumps(bare.to_dict(), allow_nan=False))
    assert b["resolution_db"] is None and b["averages"] is None and b["signal"] is None


def test_the_card_shows_the_facts_a_table_and_the_plot(from_file):
    html = from_file._repr_html_()
    for fact in ("Frequency response of motor_speed_rad_s", "240, 1-200 Hz", "4 spectra averaged",
                 "155 lines below 0.8", "frequency [Hz]", "gain [dB]", "phase [deg]", "stim.csv", "<svg"):
        assert fact in html, fact
    assert int(np.sum(COHERENCE < 0.8)) == 155
    assert html.count("<tr>") >= 8


def test_plot_is_a_bode_plot_with_the_coherence_and_its_poor_lines_marked(measured):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    axes = measured.plot()
    fig = axes[0].figure
    try:
        assert len(axes) == 3 and all(ax.get_xscale() == "log" for ax in axes)
        assert [ax.get_ylabel() for ax in axes] == ["gain [dB]", "phase [deg]", "coherence [-]"]
        assert axes[-1].get_xlabel() == "frequency [Hz]"
        gain, marked = axes[0].get_lines()[:2]
        assert np.allclose(gain.get_ydata(), 20 * np.log10(np.abs(H)))
        poor = COHERENCE < 0.8
        assert np.allclose(marked.get_xdata(), F[poor]) and marked.get_label() == "coherence < 0.8"
        assert np.allclose(axes[2].get_lines()[0].get_ydata(), COHERENCE)
        assert fig.get_layout_engine() is not None
        assert layout_faults(fig) == []
    finally:
        plt.close(fig)


def test_stroke_check_and_margins_print_one_line_with_units():
    q = np.radians([-30.0, 0.0, 30.0])
    arr = np.array([1.0, 2.0, 3.0])
    check = StrokeCheck(q=q, q0=0.0, ratio=arr * 100, motor_inertia=arr * 1e-4, inertia=arr, stable=np.ones(3, bool),
                        max_pole_real=-arr, gain_margin_db=np.array([9.0, 12.0, 8.5]),
                        phase_margin_deg=np.array([61.0, 69.0, 64.0]), sensitivity_peak_db=np.array([4.9, 3.4, 4.2]),
                        bandwidth_hz=np.array([17.0, 12.4, 15.0]))
    assert repr(check) == ("<StrokeCheck: 3 points -30 deg..30 deg, stable at every point, worst GM 8.5 dB at 30 deg, "
                           "PM 61 deg at -30 deg, Ms 4.9 dB at -30 deg, bandwidth 12.4 Hz at 0 deg>")
    margins = Margins((14.05,), (40.0,), (69.2,), (8.0,), (0.031,), 14.05, 69.2, 0.031, 0.981, 8.0, 50.0, 3.35, 12.4,
                      8.0, -20.0, True, -15.0)
    assert repr(margins) == ("<Margins: GM 14.05 dB, PM 69.2 deg, delay margin 31 ms, disk margin 0.981, "
                             "Ms 3.35 dB, bandwidth 12.4 Hz>")
    unstable = Margins((), (), (), (), (), math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan,
                       math.nan, 8.0, 0.0, False, 2.5, unstable_closed_loop_poles=2)
    assert repr(unstable) == ("<Margins: closed loop unstable: 2 closed-loop poles in the right half-plane, the "
                              "largest real part 2.5 1/s>")
