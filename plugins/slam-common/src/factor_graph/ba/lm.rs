//! Full bundle adjustment: Levenberg–Marquardt over poses and points, each step solved in
//! Schur form.

use super::*;

/// Optimises the non-fixed poses and all points in place by Levenberg–Marquardt over the
/// observations that are active and in front of their camera at the start (the others are
/// ignored throughout; a step that would move a point behind a camera observing it is
/// rejected). Points without such an observation, and non-fixed poses that observe none,
/// are left as they are; points seen only from fixed poses are optimised.
pub fn bundle_adjust(problem: &mut Problem, options: &Options) -> Report {
    let structure = Structure::new(problem);
    let mut poses: Vec<Isometry3<f64>> =
        problem.poses.iter().map(|p| p.camera_from_world).collect();
    let mut points = problem.points.clone();
    let mut cost = structure.cost(problem, &poses, &points, options.robust);
    let initial_cost = cost;
    let mut iterations = 0;
    if structure.points() > 0 {
        let mut normal = Normal::new(&structure);
        let mut solver = SchurSolver::new(&structure);
        let mut damping: Option<Damping> = None;
        'iterations: while iterations < options.iterations {
            iterations += 1;
            normal.linearise(problem, &structure, &poses, &points, options.robust);
            let damping = damping.get_or_insert_with(|| {
                Damping::new(options.initial_lambda * normal.max_diagonal())
            });
            let mut accepted = false;
            for _ in 0..MAX_TRIALS {
                let lambda = damping.lambda;
                let Some(step) = solver.solve(&structure, &normal, lambda) else {
                    damping.reject();
                    continue;
                };
                let predicted = step.predicted_decrease(&normal, lambda);
                if predicted.is_nan() || predicted <= 0.0 {
                    // A zero step: the gradient vanishes.
                    break 'iterations;
                }
                let mut trial_poses = poses.clone();
                for (d, &pose) in step.poses.iter().zip(&structure.pose_index) {
                    trial_poses[pose] = update_pose(d, &poses[pose]);
                }
                let mut trial_points = points.clone();
                for (d, &point) in step.points.iter().zip(&structure.point_index) {
                    trial_points[point] += d;
                }
                let trial_cost =
                    structure.cost(problem, &trial_poses, &trial_points, options.robust);
                if damping.update((cost - trial_cost) / predicted) {
                    let decrease = cost - trial_cost;
                    poses = trial_poses;
                    points = trial_points;
                    cost = trial_cost;
                    accepted = true;
                    if decrease <= RELATIVE_DECREASE * (cost + decrease) {
                        break 'iterations;
                    }
                    break;
                }
            }
            if !accepted {
                break;
            }
        }
        for &pose in &structure.pose_index {
            problem.poses[pose].camera_from_world = poses[pose];
        }
        for &point in &structure.point_index {
            problem.points[point] = points[point];
        }
    }
    Report {
        iterations,
        initial_cost,
        final_cost: cost,
    }
}
