//! A vehicle's generalized path, asked of the planner.

use std::collections::BTreeMap;
use std::time::Instant;

use tcpf_core::model::path::GeneralizedPath;
use tcpf_core::msg::PathMsg;
use tokio::sync::mpsc;
use zenoh::sample::SampleKind;
use zenoh::Session;

use crate::codec::decode;
use crate::error::{failed, Result};
use crate::keys::{Keys, Role};
use crate::rejected::Rejected;
use crate::waits::Timeouts;

/// Asks the planner for the paths of `ids`, retrying until the startup timeout.
pub async fn fetch_paths(
    session: &Session,
    keys: &Keys,
    ids: &[u32],
    timeouts: &Timeouts,
    rejected: &Rejected,
) -> Result<Vec<(u32, GeneralizedPath)>> {
    let deadline = Instant::now() + timeouts.startup;
    let selector = if ids.len() == 1 {
        keys.plan(ids[0])
    } else {
        keys.plan("*")
    };
    // A planner still planning is not there yet: ask again the moment its token appears,
    // which it declares once it serves (the fleet's first tick waited up to a whole retry
    // period for the last agent's path). Plain gets, not a querier, whose matching would ask
    // only once the router passed the planner's queryable declaration: access control that
    // hides it would then keep a vehicle from ever asking.
    let (planner_up, mut appeared) = mpsc::unbounded_channel();
    let _planner = session
        .liveliness()
        .declare_subscriber(keys.alive(Role::Planner, 0))
        .callback(move |sample| {
            if sample.kind() == SampleKind::Put {
                let _ = planner_up.send(());
            }
        })
        .await
        .map_err(|e| failed!("cannot follow liveliness: {e}"))?;
    let mut found: BTreeMap<u32, GeneralizedPath> = BTreeMap::new();
    loop {
        let replies = session
            .get(selector.clone())
            .timeout(timeouts.path_query)
            .await
            .map_err(|e| failed!("cannot query {selector}: {e}"))?;
        while let Ok(reply) = replies.recv_async().await {
            let Ok(sample) = reply.result() else { continue };
            let key = sample.key_expr().as_str().to_string();
            match decode::<PathMsg>(&sample.payload().to_bytes()) {
                Ok(m) if Keys::id_of(&key) == Some(m.id) => {
                    found.insert(m.id, m.path);
                }
                Ok(_) => rejected.wrong_sender(&key),
                Err(e) => rejected.invalid(e, &key),
            }
        }
        let missing: Vec<u32> = ids.iter().copied().filter(|i| !found.contains_key(i)).collect();
        if missing.is_empty() {
            return Ok(ids.iter().map(|i| (*i, found[i])).collect());
        }
        if Instant::now() >= deadline {
            // Why: no planner at all (one that served a running fleet and left, say), or one
            // this identity may not ask.
            let planner = session
                .liveliness()
                .get(keys.alive(Role::Planner, 0))
                .timeout(timeouts.planner_query)
                .await
                .map_err(|e| failed!("cannot query liveliness: {e}"))?;
            if planner.recv_async().await.is_err() {
                return Err(failed!(
                    "no path from the planner for vehicle(s) {missing:?}: no planner of this mission is on the bus, or none this identity may see (one that served the fleet may have left once it ran: start `tcpf planner` for this mission again; or the router's access control hides it)"
                ));
            }
            return Err(failed!(
                "no path from the planner for vehicle(s) {missing:?} within {:.0} s (does the router's access control let this identity ask for it?)",
                timeouts.startup.as_secs_f64()
            ));
        }
        let _ = tokio::time::timeout(timeouts.path_retry, appeared.recv()).await;
    }
}
