//! Running a scene forward in time (the thesis' M2T).

use crate::error::{CordisError, Result};
use crate::plan::{Plan, Scratch};
use crate::{Scene, Trajectory, Vec3};

/// A compiled scene with its state: x(n), x(n-1) and step scratch.
#[derive(Clone, Debug)]
pub struct Simulator {
    plan: Plan,
    params: Vec<f64>,
    x: Vec<Vec3>,
    x_prev: Vec<Vec3>,
    scratch: Scratch,
    /// x(n-1) kept by [`Simulator::step`] to undo a diverged step (the step overwrites it).
    undo: Vec<Vec3>,
    /// The stateful passes' state before the step, for the same undo (empty without them).
    undo_state: Vec<f64>,
    /// Index n of the current frame x(n).
    frame: usize,
}

impl Simulator {
    pub fn new(scene: &Scene) -> Result<Self> {
        let plan = Plan::compile(scene)?;
        let params = scene.param_values();
        Ok(Self::from_plan(plan, params))
    }

    /// A simulator on a compiled plan with an explicit parameter vector.
    pub fn from_plan(plan: Plan, params: Vec<f64>) -> Self {
        assert_eq!(
            params.len(),
            plan.layout.len,
            "parameter vector of the wrong length"
        );
        let mut scratch = plan.scratch();
        plan.reset_state(&params, &mut scratch);
        Simulator {
            x: plan.x0.clone(),
            x_prev: plan.x_minus1.clone(),
            undo_state: scratch.state.clone(),
            scratch,
            undo: plan.x0.clone(),
            plan,
            params,
            frame: 0,
        }
    }

    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// Current positions x(n).
    pub fn positions(&self) -> &[Vec3] {
        &self.x
    }

    /// Index n of the current frame.
    pub fn frame(&self) -> usize {
        self.frame
    }

    /// State of the stateful passes at the current frame (TGR tendons: `[y(n), y(n-1)]` per
    /// instance; see [`crate::forces::stateful`]).
    pub fn state(&self) -> &[f64] {
        &self.scratch.state
    }

    /// Advances one step; a non-finite or runaway position is an error naming the frame and
    /// particle (the state is then left as it was).
    pub fn step(&mut self) -> Result<()> {
        // A step leaves x(n) in `x_prev` and overwrites x(n-1): keep only that one (no
        // allocation), and undo by swapping back.
        self.undo.copy_from_slice(&self.x_prev);
        self.undo_state.copy_from_slice(&self.scratch.state);
        if let Some(i) = self.step_unchecked() {
            std::mem::swap(&mut self.x, &mut self.x_prev);
            self.x_prev.copy_from_slice(&self.undo);
            self.scratch.state.copy_from_slice(&self.undo_state);
            self.scratch.frame -= 1;
            self.frame -= 1;
            return Err(self.diverged(self.frame + 1, i));
        }
        Ok(())
    }

    /// Advances one step without saving the state; returns the first bad particle, if any.
    fn step_unchecked(&mut self) -> Option<usize> {
        self.frame += 1;
        self.plan.step(
            &self.params,
            &mut self.x,
            &mut self.x_prev,
            &mut self.scratch,
        )
    }

    /// The error of a step to `frame` that put `particle` beyond the guard
    /// ([`crate::runaway`]), with the limit it crossed.
    fn diverged(&self, frame: usize, particle: usize) -> CordisError {
        let o = self.plan.layout.gravity_offset;
        let g = Vec3::from_column_slice(&self.params[o..o + 3]).norm();
        let limit = self.scratch.runaway.limit(frame, g);
        CordisError::Diverged {
            frame,
            particle,
            message: format!(
                "position is not finite or beyond {limit:.3e} m of the start's centre (10^6 \
                 times the scene's size and reach at its speeds); reduce dt or stiffness (see \
                 `cordis check`)"
            ),
        }
    }

    /// Frames x(0)…x(T-1) from the current state (frame 0 of the result is the current x).
    pub fn run(&mut self, frames: usize) -> Result<Trajectory> {
        let n = self.plan.n;
        let mut traj = Trajectory::zeros(frames, n).with_dt(self.plan.dt);
        if frames == 0 {
            return Ok(traj);
        }
        traj.set_frame(0, &self.x);
        for t in 1..frames {
            if let Some(i) = self.step_unchecked() {
                return Err(self.diverged(self.frame, i));
            }
            traj.set_frame(t, &self.x);
        }
        Ok(traj)
    }
}

impl Scene {
    /// Simulates `frames` frames from the initial state (frame 0 = initial positions), with
    /// unknown parameters at their [`crate::Param::value`].
    pub fn simulate(&self, frames: usize) -> Result<Trajectory> {
        Simulator::new(self)?.run(frames)
    }
}
