"""The Python half of vinebench's "gtsam" backend: a factor graph on GTSAM's own ISAM2
(Kaess et al., "iSAM2: Incremental smoothing and mapping using the Bayes tree", IJRR 31(2),
2012) and CombinedImuFactor (Forster et al., "On-Manifold Preintegration for Real-Time
Visual-Inertial Odometry", IEEE T-RO 33(1), 2017), driven through GTSAM's Python wrapper.

The Rust side (plugins/slam-common/src/factor_graph/backend/gtsam.rs) checks every input (kinds, keys,
finite numbers, positive sigmas, variables inserted once and before use) and asks for
estimates one variable at a time; this module only translates requests into GTSAM calls. Requests and
replies are little-endian byte strings whose layout is documented in the bridge's FFI crate
(plugins/gtsam-backend/ffi/src/lib.rs); `Graph.handle` is the single entry point.
"""

import math
import struct

import numpy as np
import gtsam

POSE, VEL, BIAS = ord("x"), ord("v"), ord("b")
INDEX_MASK = (1 << 56) - 1
# Raw Values.insert would store a numpy velocity as a dynamic Vector; CombinedImuFactor reads
# it back as a Vector3 (GTSAM converts), and extractVectors finds it.


def _pose(q):
    """(qw, qx, qy, qz, tx, ty, tz) -> gtsam.Pose3 (world_from_body)."""
    return gtsam.Pose3(gtsam.Rot3.Quaternion(q[0], q[1], q[2], q[3]), np.array(q[4:7]))


def _bias(b):
    """(accel xyz, gyro xyz) -> ConstantBias; GTSAM's bias vector order is accel, gyro too."""
    return gtsam.imuBias.ConstantBias(np.array(b[0:3]), np.array(b[3:6]))


def _diag(sigmas):
    return gtsam.noiseModel.Diagonal.Sigmas(np.array(sigmas, dtype=float))


class _Reader:
    __slots__ = ("buf", "pos")

    def __init__(self, buf):
        self.buf = buf
        self.pos = 0

    def u8(self):
        self.pos += 1
        return self.buf[self.pos - 1]

    def u64(self):
        (v,) = struct.unpack_from("<Q", self.buf, self.pos)
        self.pos += 8
        return v

    def f64s(self, n):
        v = struct.unpack_from("<%dd" % n, self.buf, self.pos)
        self.pos += 8 * n
        return v

    def array(self, n):
        v = np.frombuffer(self.buf, dtype="<f8", count=n, offset=self.pos)
        self.pos += 8 * n
        return v


def _key(kind, index):
    return gtsam.symbol(chr(kind), index)


class Graph:
    """One ISAM2 with the bookkeeping that GTSAM leaves to its caller: factors and values
    waiting for the next update, factor ids to GTSAM's factor indices, and the estimate."""

    def __init__(self, config):
        r = _Reader(config)
        threshold, skip, wildfire = r.f64s(1)[0], r.u64(), r.f64s(1)[0]
        self.max_iterations = r.u64()
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(threshold)
        params.relinearizeSkip = skip
        # Gauss-Newton steps with GTSAM's wildfire threshold for partial back-substitution.
        params.setOptimizationParams(gtsam.ISAM2GaussNewtonParams(wildfire))
        params.setFactorization("CHOLESKY")
        self.threshold = threshold
        self.isam = gtsam.ISAM2(params)
        self.pending_values = {}  # key -> value, inserted but not yet given to ISAM2
        self.pending_factors = []  # (id, factor) added since the last update
        self.index = {}  # factor id -> GTSAM factor index
        self.plain = {}  # factor id -> the factor without its robust kernel
        self.remove_indices = []
        self.estimate = gtsam.Values()

    def handle(self, request):
        op = request[0]
        r = _Reader(request)
        r.pos = 1
        if op == ord("i"):
            return self._insert(r)
        if op == ord("a"):
            return self._add(r)
        if op == ord("r"):
            return self._remove(r.u64())
        if op == ord("u"):
            return self._update(r.u8() != 0)
        if op == ord("e"):
            return self._error(r.u64())
        if op == ord("v"):
            return self._value(r.u8(), r.u64())
        if op == ord("c"):
            return self._marginal(r.u8(), r.u64())
        raise ValueError("unknown request %r" % chr(op))

    # -- requests ----------------------------------------------------------------------

    def _insert(self, r):
        kind, index = r.u8(), r.u64()
        if kind == POSE:
            value = _pose(r.f64s(7))
        elif kind == VEL:
            value = np.array(r.f64s(3))
        elif kind == BIAS:
            value = _bias(r.f64s(6))
        else:
            raise ValueError("unknown variable kind %r" % chr(kind))
        self.pending_values[_key(kind, index)] = value
        return b""

    def _add(self, r):
        fid, kind = r.u64(), r.u8()
        if kind == ord("p"):
            key = r.u64()
            pose, sigmas = _pose(r.f64s(7)), r.f64s(6)
            factor = gtsam.PriorFactorPose3(_key(POSE, key), pose, _diag(sigmas))
            plain = factor
        elif kind == ord("v"):
            key = r.u64()
            vel, sigma = np.array(r.f64s(3)), r.f64s(1)[0]
            noise = gtsam.noiseModel.Isotropic.Sigma(3, sigma)
            factor = gtsam.PriorFactorVector(_key(VEL, key), vel, noise)
            plain = factor
        elif kind == ord("b"):
            key = r.u64()
            bias = _bias(r.f64s(6))
            sa, sg = r.f64s(2)
            noise = _diag([sa, sa, sa, sg, sg, sg])
            factor = gtsam.PriorFactorConstantBias(_key(BIAS, key), bias, noise)
            plain = factor
        elif kind == ord("B"):
            a, b = r.u64(), r.u64()
            pose, sigmas = _pose(r.f64s(7)), r.f64s(6)
            robust, k = r.u8(), r.f64s(1)[0]
            noise = _diag(sigmas)
            plain = gtsam.BetweenFactorPose3(_key(POSE, a), _key(POSE, b), pose, noise)
            if robust == 0:
                factor = plain
            else:
                m = gtsam.noiseModel.mEstimator
                kernel = m.Huber.Create(k) if robust == 1 else m.Cauchy.Create(k)
                model = gtsam.noiseModel.Robust.Create(kernel, noise)
                factor = gtsam.BetweenFactorPose3(_key(POSE, a), _key(POSE, b), pose, model)
        elif kind == ord("P"):
            # A position-only prior on a pose's translation: GPSFactor's error is
            # pose.translation() - measured, whitened by the diagonal sigmas.
            key = r.u64()
            position, sigmas = np.array(r.f64s(3)), r.f64s(3)
            factor = gtsam.GPSFactor(_key(POSE, key), position, _diag(sigmas))
            plain = factor
        elif kind == ord("I"):
            factor = self._imu(r)
            plain = factor
        else:
            raise ValueError("unknown factor kind %r" % chr(kind))
        self.pending_factors.append((fid, factor))
        self.plain[fid] = plain
        return b""

    def _imu(self, r):
        a, b = r.u64(), r.u64()
        bias = _bias(r.f64s(6))
        acc_nd, gyro_nd, acc_rw, gyro_rw, gravity, integration = r.f64s(6)
        n = r.u64()
        samples = r.array(7 * n).reshape(n, 7)
        i3 = np.eye(3)
        params = gtsam.PreintegrationCombinedParams.MakeSharedU(gravity)
        # Continuous-time densities squared, as GTSAM's integrateMeasurement divides white
        # noise by dt and multiplies random walks and integration noise by dt itself.
        params.setAccelerometerCovariance(i3 * acc_nd**2)
        params.setGyroscopeCovariance(i3 * gyro_nd**2)
        params.setBiasAccCovariance(i3 * acc_rw**2)
        params.setBiasOmegaCovariance(i3 * gyro_rw**2)
        params.setIntegrationCovariance(i3 * integration)
        pim = gtsam.PreintegratedCombinedMeasurements(params, bias)
        for s in samples:
            pim.integrateMeasurement(s[1:4], s[4:7], s[0])
        return gtsam.CombinedImuFactor(
            _key(POSE, a), _key(VEL, a), _key(POSE, b), _key(VEL, b),
            _key(BIAS, a), _key(BIAS, b), pim,
        )

    def _remove(self, fid):
        self.plain.pop(fid, None)
        for i, (pending, _) in enumerate(self.pending_factors):
            if pending == fid:
                del self.pending_factors[i]
                return b"\x01"
        index = self.index.pop(fid, None)
        if index is None:
            return b"\x00"
        self.remove_indices.append(index)
        return b"\x01"

    def _error(self, fid):
        factor = self.plain.get(fid)
        if factor is None:
            return b"\x00" + struct.pack("<d", math.nan)
        values = self._values_for(factor.keys())
        return b"\x01" + struct.pack("<d", math.sqrt(2.0 * factor.error(values)))

    def _update(self, full):
        graph = gtsam.NonlinearFactorGraph()
        ids = []
        involved = set()
        for fid, factor in self.pending_factors:
            graph.add(factor)
            ids.append(fid)
            involved.update(factor.keys())
        # ISAM2 takes new values only for variables that its new factors use; the others
        # wait (their estimate stays their initial value).
        new_values = gtsam.Values()
        taken = [key for key in self.pending_values if key in involved]
        for key in taken:
            new_values.insert(key, self.pending_values[key])
        removed = self.remove_indices
        old = self.isam.getFactorsUnsafe()
        params = gtsam.ISAM2UpdateParams()
        params.removeFactorIndices = removed
        if full:
            # Every variable relinearised: ISAM2 relinearises those whose last step reaches
            # the threshold, checked at this update whatever relinearizeSkip says
            # (force_relinearize), so the threshold is 0 for the update. ISAM2 reads it
            # from its parameters at each update; isam.params() is that live object.
            before = self._full_error(old, removed, graph, new_values)
            live = self.isam.params()
            live.setRelinearizeThreshold(0.0)
            try:
                params.force_relinearize = True
                result = self.isam.update(graph, new_values, params)
                self._take_result(ids, result)
                after = 2.0 * self.isam.getFactorsUnsafe().error(self.estimate)
                iterations = 1
                while iterations < self.max_iterations:
                    again = gtsam.ISAM2UpdateParams()
                    again.force_relinearize = True
                    result = self.isam.update(gtsam.NonlinearFactorGraph(), gtsam.Values(), again)
                    self.estimate = self.isam.calculateEstimate()
                    iterations += 1
                    error = 2.0 * self.isam.getFactorsUnsafe().error(self.estimate)
                    # "Stopped decreasing": by less than a relative 1e-14 (rounding). A
                    # step that made it worse has been taken all the same (ISAM2 cannot
                    # undo an update); the report says so with error_after.
                    done = not error < after * (1.0 - 1e-14)
                    after = error
                    if done:
                        break
            finally:
                live.setRelinearizeThreshold(self.threshold)
            variables = self.isam.getLinearizationPoint().size()
            factors = result.getFactorsRecalculated()
        else:
            # One ISAM2 update and nothing else, as GTSAM's own incremental loops do: no
            # error evaluation (GTSAM's evaluateNonlinearError is off by default: it costs
            # a pass over the whole graph) and no estimate (asked for per variable).
            result = self.isam.update(graph, new_values, params)
            for fid, index in zip(ids, result.getNewFactorsIndices()):
                self.index[fid] = index
            self.estimate = None
            before = after = float("nan")
            iterations = 1
            variables = result.getVariablesReeliminated()
            factors = result.getFactorsRecalculated()
        for key in taken:
            del self.pending_values[key]
        self.pending_factors = []
        self.remove_indices = []
        head = struct.pack("<QQQdd", variables, factors, iterations, before, after)
        taken_bytes = struct.pack("<Q", len(taken)) + b"".join(
            struct.pack("<BQ", key >> 56, key & INDEX_MASK) for key in taken
        )
        return head + taken_bytes

    # -- helpers -----------------------------------------------------------------------

    def _value(self, kind, index):
        """ISAM2's current estimate of one variable (its linearisation point plus its
        step), as GTSAM's calculateEstimate(key)."""
        key = _key(kind, index)
        if kind == POSE:
            p = self.isam.calculateEstimatePose3(key)
            rt = np.concatenate([p.rotation().matrix().reshape(9), p.translation()])
            return rt.astype("<f8").tobytes()
        if kind == VEL:
            return np.asarray(self.isam.calculateEstimateVector(key), dtype="<f8").tobytes()
        return self.isam.calculateEstimateConstantBias(key).vector().astype("<f8").tobytes()

    def _marginal(self, kind, index):
        """ISAM2's marginal covariance of one pose (marginalCovariance: from its Bayes tree
        at the linearisation point), Pose3's tangent order, 36 f64 row-major."""
        if kind != POSE:
            raise ValueError("marginal covariance of a pose only, not %r" % chr(kind))
        cov = np.asarray(self.isam.marginalCovariance(_key(kind, index)), dtype="<f8")
        if cov.shape != (6, 6):
            raise ValueError("marginal covariance of shape %r" % (cov.shape,))
        return np.ascontiguousarray(cov).tobytes()

    def _take_result(self, ids, result):
        for fid, index in zip(ids, result.getNewFactorsIndices()):
            self.index[fid] = index
        self.estimate = self.isam.calculateEstimate()

    def _full_error(self, old, removed, graph, new_values):
        """2 x GTSAM's error (sum of 1/2 |r|^2, or the kernel's rho) of every live factor
        at the estimate before the update."""
        values = gtsam.Values(self._current())
        values.insert(new_values)
        gone = set(removed)
        total = graph.error(values)
        for i in range(old.size()):
            factor = old.at(i)
            if factor is not None and i not in gone:
                total += factor.error(values)
        return 2.0 * total

    def _scope(self, result):
        """The factors on the variables this update marked (those of new and removed
        factors, and those it relinearised)."""
        index = self.isam.getVariableIndex()
        factors = self.isam.getFactorsUnsafe()
        seen = set()
        graph = gtsam.NonlinearFactorGraph()
        for key in result.getMarkedKeys():
            for i in index.at(key):
                if i not in seen:
                    seen.add(i)
                    factor = factors.at(i)
                    if factor is not None:
                        graph.add(factor)
        return graph

    @staticmethod
    def _keys_of(graph):
        keys = set()
        for i in range(graph.size()):
            keys.update(graph.at(i).keys())
        return keys

    def _values_for(self, keys, extra=None):
        """The current estimate of `keys`: ISAM2's, else a pending initial value."""
        values = gtsam.Values()
        for key in keys:
            if extra is not None and extra.exists(key):
                source = extra
            elif self._current().exists(key):
                source = self._current()
            else:
                _put(values, key, self.pending_values[key])
                continue
            _copy(values, source, key)
        return values

    def _current(self):
        """Every variable's estimate (calculateEstimate), computed once after an update
        when something needs it."""
        if self.estimate is None:
            self.estimate = self.isam.calculateEstimate()
        return self.estimate


def _copy(values, source, key):
    kind = key >> 56
    if kind == POSE:
        values.insert(key, source.atPose3(key))
    elif kind == VEL:
        values.insert(key, source.atVector(key))
    else:
        values.insert(key, source.atConstantBias(key))


def _put(values, key, value):
    values.insert(key, value)
