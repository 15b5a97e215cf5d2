use crate::alloc_prelude::*;
use crate::dynamics::MultibodyLink;
use crate::dynamics::RigidBodyVelocity;
use crate::dynamics::joint::multibody_joint::multibody::link_column_ranges;
use crate::math::{DVector, Jacobian, Real};

/// A temporary workspace for various updates of the multibody.
#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Debug)]
pub(crate) struct MultibodyWorkspace {
    pub accs: Vec<RigidBodyVelocity<Real>>,
    pub ndofs_vec: DVector,
    /// Strider patch: each link's nonzero body-Jacobian column ranges `(start, len)`
    /// (`link_column_ranges`), as [`Self::column_ranges`] last computed them: read by
    /// `update_body_jacobians`, `update_mass_matrix`, `update_acceleration` and, later in
    /// the same step, `fill_jacobians_unsolved`. A copy (`Clone`) has none, so it takes
    /// the dense products until then, and `Multibody::clone_from` copies them with their
    /// key.
    pub col_ranges: Vec<Vec<(usize, usize)>>,
    /// Strider patch: what `col_ranges` were computed from: each link's parent, first dof
    /// and dof count, three words a link (`link_column_ranges` reads nothing else).
    pub col_ranges_key: Vec<usize>,
    /// Strider patch: `M J` for one link and each of the two mass matrices, reused across
    /// links and steps.
    pub mass_work: [Jacobian<Real>; 2],
    /// Strider patch: each link's nonzero body-Jacobian columns in blocks of lanes, laid
    /// out for `transposed_products_add`, reused across steps.
    pub jacobian_blocks: Vec<Vec<Real>>,
    /// Strider patch: each link's Coriolis terms over its nonzero columns, in the same
    /// layout.
    pub coriolis: Vec<Vec<Real>>,
    /// Strider patch: one link's Coriolis terms melded with its mass, in the same layout.
    pub coriolis_dt: Vec<Real>,
    /// Strider patch: what forward kinematics reads, written before it is compared with
    /// the last call's (`Multibody::kinematics_inputs_unchanged`).
    pub kinematics_inputs: Vec<u32>,
    /// Strider patch: `update_acceleration`'s position-derived forces and its copy of the
    /// generalised forces, for the energy guard; scratch.
    pub pos_forces: DVector,
    pub gen_forces: DVector,
    /// Strider patch: the energy guard's `M a` and `M v`; scratch.
    pub guard_products: [DVector; 2],
}

/// Strider patch: a copy has the workspace's sizes and none of its contents, which every
/// step writes before it reads them (the buffers are scratch). A multibody is copied
/// every few steps to take a step again (the worker's joint drives); copying the buffers,
/// about seventy allocations for a hexapod, was most of that copy's cost. (A multibody
/// copied into another's buffers, `Multibody::clone_from`, keeps that one's workspace
/// where the sizes match: stale contents, written before they are read all the same.)
impl Clone for MultibodyWorkspace {
    fn clone(&self) -> Self {
        let mut copy = Self::new();
        copy.resize(self.accs.len(), self.ndofs_vec.len());
        copy
    }
}

impl MultibodyWorkspace {
    /// Create an empty workspace.
    pub fn new() -> Self {
        MultibodyWorkspace {
            accs: Vec::new(),
            ndofs_vec: DVector::zeros(0),
            col_ranges: Vec::new(),
            col_ranges_key: Vec::new(),
            mass_work: [Jacobian::zeros(0), Jacobian::zeros(0)],
            jacobian_blocks: Vec::new(),
            coriolis: Vec::new(),
            coriolis_dt: Vec::new(),
            kinematics_inputs: Vec::new(),
            pos_forces: DVector::zeros(0),
            gen_forces: DVector::zeros(0),
            guard_products: [DVector::zeros(0), DVector::zeros(0)],
        }
    }

    /// Strider patch: whether a copy of `other` would have this workspace's sizes (what
    /// `Clone` gives a copy; the contents are scratch).
    pub fn same_sizes(&self, other: &Self) -> bool {
        self.accs.len() == other.accs.len() && self.ndofs_vec.len() == other.ndofs_vec.len()
    }

    /// Strider patch: the links' column ranges, taken out of the workspace (to be put back
    /// in `col_ranges`): computed again only when a link's parent, first dof or dof count
    /// changed since they were last computed, the same ranges otherwise. Three times a
    /// step, recomputing them was about 1 % of a trial's instructions.
    pub fn column_ranges(&mut self, links: &[MultibodyLink]) -> Vec<Vec<(usize, usize)>> {
        let mut ranges = core::mem::take(&mut self.col_ranges);
        let key = |link: &MultibodyLink| {
            [
                link.parent_internal_id,
                link.assembly_id,
                link.joint.ndofs(),
            ]
        };
        let unchanged = ranges.len() == links.len()
            && self.col_ranges_key.len() == 3 * links.len()
            && links
                .iter()
                .zip(self.col_ranges_key.chunks_exact(3))
                .all(|(link, k)| k == key(link));
        if !unchanged {
            link_column_ranges(links, &mut ranges);
            self.col_ranges_key.clear();
            self.col_ranges_key.extend(links.iter().flat_map(key));
        }
        debug_assert!(
            {
                let mut fresh = Vec::new();
                link_column_ranges(links, &mut fresh);
                fresh == ranges
            },
            "the cached column ranges are not the links'"
        );
        ranges
    }

    /// Resize the workspace so it is enough for `nlinks` links.
    pub fn resize(&mut self, nlinks: usize, ndofs: usize) {
        self.accs.resize(nlinks, RigidBodyVelocity::zero());
        self.ndofs_vec = DVector::zeros(ndofs)
    }
}
