"""
Certify a gain range with the closed form
=========================================

Which remote gains ``(K_r, B_r)`` keep the teleoperator stable for every delay up to
``T_l* = T_r* = 1 s``? :func:`teleopkit.certification.certify_gains` answers for a whole box of
gains and returns a certificate: the verdict, the admissible polytope inside the box, the delay
margin of the box and the assumptions the verdict rests on. This tutorial uses the closed-form
condition of Nuño et al. (``method="nuno"``), which is instant.
"""

# %%
import os

import matplotlib.pyplot as plt
import numpy as np

from teleopkit.certification import certify_gains, load_certificate
from teleopkit.certification.gain_sets import GainBox
from teleopkit.certification.report import certificate_table
from teleopkit.model.params import paper_setup
from teleopkit.safety.factory import layer_for

BUDGET = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full")
SMALL = BUDGET == "small"

params = paper_setup()  # K_l = 25, B_l = 10 on both joints

# %%
# A box that is certified
# -----------------------
# Per joint the closed form asks ``4 B_l B_r > (T_l* + T_r*)^2 K_l K_r``. The worst corner of a
# box is the largest ``K_r`` with the smallest ``B_r``.
box = GainBox.uniform(kr=(5.0, 10.0), br=(30.0, 60.0))
cert = certify_gains(params, box, tl_max=1.0, tr_max=1.0, method="nuno")
print(cert.certified, cert.method, cert.gain_variation)
print(f"delay margin of the box: {cert.delay_margin:.4f} s")

# %%
# The margin is the largest common bound ``T* = T_l* = T_r*`` for which the whole box passes:
# ``sqrt(B_l B_r,min / (K_l K_r,max)) = sqrt(10 * 30 / (25 * 10))``.
print(np.sqrt(10 * 30 / (25 * 10)))

# %%
# What the verdict rests on, and the same text that ``teleopkit certify`` prints:
for text in cert.assumptions:
    print("-", text)
print()
print(certificate_table([cert]))

# %%
# A box that is not
# -----------------
# Stiffer gains with little damping violate the condition at the worst corner. The certificate
# names the violating vertex; its polytope is the part of the box that does satisfy the closed
# form (the box cut by one half-plane per joint), which is what a safety layer projects onto.
wide = GainBox.uniform(kr=(1.0, 50.0), br=(1.0, 150.0))
wide_cert = certify_gains(params, wide, 1.0, 1.0, method="nuno")
print(wide_cert.certified)
print(wide_cert.violation)
print(wide_cert.polytope.joint_vertices(0).round(3))

# %%
# Certificates serialise to JSON (``teleopkit certify --json``) and back. Reading one for use
# goes through ``load_certificate``, which parses it and re-derives what it claims (an edited
# file is refused in one line):
text = wide_cert.to_json(indent=None)
again = load_certificate(text)
print(text[:300], "...")
print(again.delay_margin == wide_cert.delay_margin)

# %%
# The admissible set of joint 1
# -----------------------------
# The half-plane boundary ``B_r = (T_l* + T_r*)^2 K_l K_r / (4 B_l)`` moves with the delay bound;
# the grey polygon is the certified set for ``T* = 1 s``. A raw gain outside it (the cross) is
# mapped by :class:`teleopkit.safety.SafetyLayer` to the nearest certified gain (the dot).
layer = layer_for(wide_cert)
raw = np.array([40.0, 40.0, 60.0, 60.0])
projection = layer.project(raw)
print(projection.action, projection.distance, layer.active_labels(projection.active))

fig, ax = plt.subplots(figsize=(6, 4.5), layout="constrained")
polygon = wide_cert.polytope.joint_vertices(0)
ax.fill(polygon[:, 0], polygon[:, 1], color="0.85", label="certified, T* = 1 s")
kr = np.linspace(0.0, 50.0, 2)
bounds = (0.5, 1.0, 1.5) if SMALL else (0.25, 0.5, 0.75, 1.0, 1.25, 1.5)
for t_star in bounds:
    ax.plot(kr, (2 * t_star) ** 2 * 25.0 * kr / (4 * 10.0), lw=1,
            label=rf"$4 B_l B_r = (2 \cdot {t_star:g})^2 K_l K_r$")
ax.plot(*raw[[0, 2]], "kx", ms=9, label="raw action")
ax.plot(*projection.action[[0, 2]], "ko", label="projected")
ax.set_xlim(0, 52)
ax.set_ylim(0, 155)
ax.set_xlabel(r"$K_r$ (joint 1)")
ax.set_ylabel(r"$B_r$ (joint 1)")
ax.legend(fontsize="small", loc="upper left")

# %%
# Delay margin against the box
# ----------------------------
# For boxes ``K_r in [1, k]``, ``B_r in [b, 150]`` the margin grows with the smallest damping and
# shrinks with the largest stiffness.
k_values = np.linspace(2.0, 50.0, 12 if SMALL else 49)
fig, ax = plt.subplots(figsize=(6, 3.5), layout="constrained")
for b_min in (10.0, 30.0, 60.0, 120.0):
    margins = [certify_gains(params, GainBox.uniform((1.0, k), (b_min, 150.0)), 1.0, 1.0,
                             method="nuno").delay_margin for k in k_values]
    ax.plot(k_values, margins, label=rf"$B_{{r,\min}} = {b_min:g}$")
ax.axhline(1.0, color="k", lw=0.8, ls="--")
ax.set_xlabel(r"largest $K_r$ of the box")
ax.set_ylabel("delay margin T* [s]")
ax.legend()
plt.show()
