//! The route's fixed sizes: what the planner's arrays hold and how long a
//! route may last.

/// The most waypoints a route holds.
pub const ROUTE_CAPACITY: usize = 64;

/// The most segments a plan holds: per waypoint, the line that arrives at
/// it and either the two halves of its corner blend or its stop's three
/// (a pivot, the dwell, a pivot).
pub const MAX_SEGMENTS: usize = 4 * ROUTE_CAPACITY;

/// The longest route, in ticks (2³¹: 248 days at 100 Hz, 24.8 days at
/// 1 kHz), so that a route's elapsed ticks never come near the `u32`
/// wrap that would make them ambiguous.
pub const MAX_ROUTE_TICKS: u32 = 1 << 31;
