//! What a kernel answers for one ray ([`Hit`]) and which answer it looks for
//! ([`HitPolicy`]). They live here, below the kernels, because the
//! hit-agreement rules (the `agreement` module, which uses this one) judge
//! the same type the kernels return.

/// A kernel's answer for one ray: the distance and triangle of its hit (the
/// closest, or for an any-hit ray the one that occluded it), or a miss.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Hit distance (a kernel's t_far for a miss).
    pub t: f32,
    /// The triangle hit; `None`: a miss.
    pub prim: Option<u32>,
}

impl Hit {
    /// A miss at distance `t`.
    #[must_use]
    pub fn miss(t: f32) -> Hit {
        Hit { t, prim: None }
    }
    /// From a kernel's hit record: `t` and the triangle id word, where the
    /// kernels store -1 (any negative i32) for none.
    #[must_use]
    pub fn from_record(t: f32, prim: u32) -> Hit {
        Hit {
            t,
            prim: ((prim as i32) >= 0).then_some(prim),
        }
    }
    /// Whether the ray hit (or, any-hit, was occluded).
    #[must_use]
    pub fn is_hit(self) -> bool {
        self.prim.is_some()
    }
}

/// Which hit a traversal looks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HitPolicy {
    /// The closest hit within the ray's interval.
    Closest,
    /// Any hit within the interval: the ray stops at its first (shadow rays).
    Any,
}

impl HitPolicy {
    /// Whether the traversal may stop at the first hit.
    #[must_use]
    pub fn is_any(self) -> bool {
        self == HitPolicy::Any
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_negative_record_is_a_miss_and_others_name_the_triangle() {
        assert_eq!(Hit::from_record(1.0, u32::MAX), Hit::miss(1.0));
        assert_eq!(Hit::from_record(2.0, 7).prim, Some(7));
        assert!(!Hit::from_record(2.0, 0x8000_0000).is_hit());
        assert!(HitPolicy::Any.is_any() && !HitPolicy::Closest.is_any());
    }
}
