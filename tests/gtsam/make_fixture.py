"""Writes GTSAM's own optimum of a 3D g2o pose graph, for the backend tests.

Reads the file with gtsam.readG2o(path, is3D=True), adds the prior on the first pose that
GTSAM's python/gtsam/examples/Pose3SLAMExample_g2o.py adds (Pose3() with variances 1e-6 rad^2
for rotation and 1e-4 m^2 for translation), and runs GTSAM's Gauss-Newton to convergence.
Prints the fixture to stdout: a header of '#' lines (the command, the graph, graph.error at
the initial values and at the optimum), then one line per pose:
    key tx ty tz qx qy qz qw
with every number written with repr() (shortest round-trip form).

Run with the venv scripts/setup.sh makes:
    target/gtsam-venv/bin/python tests/gtsam/make_fixture.py \
        plugins/slam-common/tests/fixtures/pose3example.txt \
        > plugins/slam-common/tests/fixtures/pose3example.gtsam.txt
"""

import sys

import numpy as np
import gtsam


def main(path):
    graph, initial = gtsam.readG2o(path, True)
    prior = gtsam.noiseModel.Diagonal.Variances(np.array([1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4]))
    first = initial.keys()[0]
    graph.add(gtsam.PriorFactorPose3(first, gtsam.Pose3(), prior))
    params = gtsam.GaussNewtonParams()
    params.setMaxIterations(100)
    params.setRelativeErrorTol(1e-14)
    params.setAbsoluteErrorTol(1e-15)
    optimizer = gtsam.GaussNewtonOptimizer(graph, initial, params)
    result = optimizer.optimize()
    name = path.rsplit("/", 1)[-1]
    out = sys.stdout
    out.write("# GTSAM %s's optimum of %s (GTSAM's examples/Data, BSD licence; shipped in the\n"
              % (gtsam.__version__ if hasattr(gtsam, "__version__") else "4.3.0", name))
    out.write("# gtsam==4.3.0 wheel as gtsam/Data/%s), made by\n" % name)
    out.write("#   target/gtsam-venv/bin/python tests/gtsam/make_fixture.py %s > %s\n"
              % (path, path.replace(".txt", ".gtsam.txt")))
    out.write("# graph: readG2o(is3D=True) and PriorFactorPose3(%d, Pose3(), Diagonal.Variances(\n"
              "#   1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4)) as in Pose3SLAMExample_g2o.py\n" % first)
    out.write("# solver: GaussNewtonOptimizer, relativeErrorTol 1e-14, absoluteErrorTol 1e-15, "
              "%d iterations\n" % optimizer.iterations())
    out.write("# initial_error %r\n" % graph.error(initial))
    out.write("# final_error %r\n" % graph.error(result))
    out.write("# key tx ty tz qx qy qz qw\n")
    for key in result.keys():
        pose = result.atPose3(key)
        t = pose.translation()
        q = pose.rotation().toQuaternion()
        numbers = [t[0], t[1], t[2], q.x(), q.y(), q.z(), q.w()]
        out.write("%d %s\n" % (key, " ".join(repr(float(x)) for x in numbers)))


if __name__ == "__main__":
    main(sys.argv[1])
