"""The body vibration's figures (`robot.vibration`, the `vibration` factor of
configs/study/realism/factors-*.toml) from a field dataset's IMU logs: a Clearpath Husky A200
(four wheels, no suspension) in the BorealTC repository (norlab-ulaval/BorealTC, CC0; read at
commit fe64e38), which ships Vulpi et al. 2021's farm-site logs (J. Terramechanics 96,
119-131; data/vulpi/<TERRAIN>/imu_*.csv at 50 Hz and pro_*.csv with the wheel speeds) and
its own (LaRocque et al. 2024, arXiv:2403.16877; data/borealtc/<TERRAIN>/, IMU at 100 Hz).

    python3 docs/realism/vibration-fit.py DATA_DIR [TERRAIN...]          # band RMS (Vulpi)
    python3 docs/realism/vibration-fit.py --speed DATA_DIR [TERRAIN...]  # exponent (BorealTC)

DATA_DIR holds the repository's `data/` folder. Windows of 5.12 s where the robot drives
straight and steadily (left and right wheel speeds within 0.15 m/s of each other, 0.10 for
BorealTC; the speed's spread under 0.4 m/s, 0.15 for BorealTC; moving); in each the mean is
removed (gravity, biases, the slope) and a Hann-windowed one-sided periodogram taken. The
band RMS is the mean periodogram's integral over the band; the speed exponent a log-log
least-squares fit of each window's 0.5-25 Hz RMS against its mean wheel speed. Needs numpy.
"""

import glob
import sys

import numpy as np

AXES = ("ax", "ay", "az", "wx", "wy", "wz")
BANDS = [0.5, 2.0, 5.0, 10.0, 25.0]


def windows(data, dataset, terrain, n, max_turn, max_spread):
    """Yields (mean wheel speed, {axis: one-sided periodogram}, frequencies) per window."""
    for imu_file in sorted(glob.glob(f"{data}/{dataset}/{terrain}/imu_*.csv")):
        imu = np.genfromtxt(imu_file, delimiter=",", names=True)
        pro = np.genfromtxt(imu_file.replace("imu_", "pro_"), delimiter=",", names=True)
        t = imu["time"]
        if len(t) < n:
            continue
        rate = round(1.0 / np.median(np.diff(t)))
        left = np.interp(t, pro["time"], pro["velL"])
        right = np.interp(t, pro["time"], pro["velR"])
        f = np.fft.rfftfreq(n, 1.0 / rate)
        w = np.hanning(n)
        for s in range(0, len(t) - n, n):
            cut = slice(s, s + n)
            v = 0.5 * (left[cut] + right[cut])
            if (np.max(np.abs(left[cut] - right[cut])) > max_turn or np.ptp(v) > max_spread
                    or np.mean(v) < 0.05):
                continue
            psd = {}
            for k in AXES:
                x = imu[k][cut] - np.mean(imu[k][cut])
                p = np.abs(np.fft.rfft(x * w)) ** 2 / (np.sum(w * w) * rate)
                p[1:-1] *= 2.0
                psd[k] = p
            yield np.mean(v), psd, f


def bands(data, terrains):
    for terrain in terrains:
        got = list(windows(data, "vulpi", terrain, 256, 0.15, 0.4))
        f = got[0][2]
        df = f[1] - f[0]
        speeds = [g[0] for g in got]
        print(f"{terrain}: {len(got)} windows, wheel speed median {np.median(speeds):.2f} m/s")
        for k in AXES:
            p = np.mean([g[1][k] for g in got], axis=0)
            rms = [np.sqrt(np.sum(p[(f >= lo) & ((f < hi) | (hi == BANDS[-1]) & (f <= hi))]) * df)
                   for lo, hi in zip(BANDS[:-1], BANDS[1:])]
            print(f"  {k} RMS per band {BANDS} Hz: " + ", ".join(f"{r:.4f}" for r in rms))


def speed(data, terrains):
    for terrain in terrains:
        rows = []
        for v, psd, f in windows(data, "borealtc", terrain, 512, 0.10, 0.15):
            band = (f >= 0.5) & (f <= 25.0)
            rows.append([v] + [np.sqrt(np.sum(psd[k][band]) * (f[1] - f[0])) for k in AXES])
        a = np.array(rows)
        exps = [np.polyfit(np.log(a[:, 0]), np.log(a[:, j + 1]), 1)[0] for j in range(6)]
        lo, hi = np.min(a[:, 0]), np.max(a[:, 0])
        print(f"{terrain}: {len(a)} windows at {lo:.2f}-{hi:.2f} m/s; exponents "
              + ", ".join(f"{k} {e:.2f}" for k, e in zip(AXES, exps))
              + f"; mean {np.mean(exps):.2f}")


if __name__ == "__main__":
    args = sys.argv[1:]
    if args and args[0] == "--speed":
        speed(args[1], args[2:] or ["SANDY_LOAM"])
    elif args:
        bands(args[0], args[1:] or ["UNPLOUGHED"])
    else:
        sys.exit(__doc__)
