//! Who is in the fleet and for how long: which process holds a role that only one may hold
//! (`claim`), whom a role waits for (`membership`), whether the recorders have a role's last
//! words (`handover`), whether a recorder's world is still there
//! (`watch`), a wait stretched by a paused process (`pause`), who is still there by the
//! liveliness changes followed (`present`), and where a vehicle's id sits in the fleet's order
//! (`roster`). Each takes what its process heard (liveliness changes, claims, replies) and `now`
//! as inputs.

pub mod claim;
pub mod handover;
pub mod membership;
pub mod pause;
pub mod present;
pub mod roster;
pub mod watch;
