"""
Bring your own delay trace
==========================

Delays measured on a real network can drive the simulator directly: a CSV file with a time column
and a delay column (seconds) becomes a :class:`teleopkit.TraceDelay`, linearly interpolated between
samples. It must start at ``t = 0`` (or before) and, for a run, last as long as the run: recorded
timestamps are refused rather than extrapolated, and so is a trace shorter than the run. This
tutorial writes such a file with pandas, simulates with it from the one-line spec
``delay="csv:PATH"`` (the same trace on both channels) and with the delay API (different traces per
channel), and checks that the gains used are certified for the trace's bound.
"""

# %%
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import teleopkit as tk
from teleopkit.certification import certify_gains
from teleopkit.certification.gain_sets import GainBox
from teleopkit.plots import plot_run

BUDGET = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full")
SMALL = BUDGET == "small"
DURATION = 10.0 if SMALL else 40.0

# %%
# A recorded trace
# ----------------
# Here the "recording" is synthetic: a 300 ms base latency with jitter sampled every 50 ms, and a
# congestion episode that pushes the delay towards 0.8 s for a few seconds.
rng = np.random.default_rng(3)
t = np.arange(0.0, DURATION + 0.05, 0.05)
congestion = 0.45 * np.exp(-(((t - 0.5 * DURATION) / 1.5) ** 2))
delay = np.clip(0.3 + congestion + 0.03 * rng.standard_normal(t.size), 0.2, 0.85)
path = Path(tempfile.gettempdir()) / "teleopkit_delay_trace.csv"
pd.DataFrame({"t": t, "delay": delay}).to_csv(path, index=False)
pd.read_csv(path).head()

# %%
# From the one-line spec
# ----------------------
# ``csv:PATH`` is what ``teleopkit simulate --delay csv:PATH`` uses. The file needs a time column
# (``t`` or ``time``) and a delay column (``delay`` or ``latency``), each name with an optional
# unit suffix (``_s``, ``_ms``, ``_us``; seconds without one), for example ``t,delay_ms``.
table = tk.simulate(gains=(10.0, 30.0), duration=DURATION, delay=f"csv:{path}", seed=0)
table[["t", "Tl", "Tr", "e_track_1"]].describe().loc[["min", "max"]]

# %%
# With the delay API
# ------------------
# :meth:`teleopkit.TraceDelay.from_csv` reads the same file; any profile can be combined with
# another one per channel. Here the backward channel gets the trace shifted by 2 s, built
# directly from arrays.
forward = tk.TraceDelay.from_csv(path)
backward = tk.TraceDelay(t, np.roll(delay, int(2.0 / 0.05)))
print(forward.bound, backward.bound)
table2 = tk.simulate(gains=(10.0, 30.0), duration=DURATION, delay=(forward, backward), seed=0)

fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True, layout="constrained")
axes[0].plot(t, delay, ".", ms=3, color="0.5", label="CSV samples")
axes[0].plot(table2["t"], table2["Tl"], label=r"$T_l$ (trace)")
axes[0].plot(table2["t"], table2["Tr"], label=r"$T_r$ (shifted trace)")
axes[0].set_ylabel("delay [s]")
axes[0].legend(fontsize="small", ncol=3)
for i in (1, 2):
    axes[1].plot(table2["t"], table2[f"e_track_{i}"], label=f"joint {i}")
axes[1].set_ylabel("tracking error [rad]")
axes[1].set_xlabel("time [s]")
axes[1].legend(fontsize="small")

# %%
# Is the run covered by a certificate?
# ------------------------------------
# A profile declares an upper ``bound`` (by default the largest sample) and the simulator refuses
# any delay above it. Certify the gains for that bound: the closed form covers every delay
# variation within it, so this run is inside a certified setting.
bound = max(forward.bound, backward.bound)
cert = certify_gains(tk.paper_setup(), GainBox.uniform((10.0, 10.0), (30.0, 30.0)),
                     tl_max=bound, tr_max=bound, method="nuno")
print(f"bound {bound:.3f} s, certified {cert.certified}, margin {cert.delay_margin:.3f} s")

# %%
# The figure of the whole run, as ``teleopkit simulate --plot`` draws it:
fig = plot_run(table2, title="K_r = 10, B_r = 30, recorded delays")
plt.show()
