//! The mission runner's states and the follower actions it asks for,
//! with the follower's status and counters given by hand.

mod common;

use common::limits;
use wmr_core::geometry::Vec2;
use wmr_core::pilot::route::{RouteCounters, RouteFollower, RouteOptions, RouteStart, RouteStatus};
use wmr_core::reference::route::{Waypoint, Waypoints};
use wmr_mavlink::{Event, FollowerAction, MissionRunner, Note, RobotMode};

fn mission() -> Waypoints {
    Waypoints::from_slice(&[
        Waypoint::pass(0.0, 0.0),
        Waypoint::pass(1.0, 0.0),
        Waypoint::stop(1.0, 1.0, 0.5),
    ])
    .unwrap()
}

fn runner() -> MissionRunner {
    MissionRunner::new(RouteStart::AsGivenHeadingKnown, limits())
}

fn apply(
    r: &mut MissionRunner,
    event: Event,
    counters: RouteCounters,
) -> (FollowerAction, Option<Note>) {
    let a = r.apply(event, &mission(), limits(), counters);
    (a.action, a.note)
}

fn running() -> RouteStatus {
    RouteStatus {
        running: true,
        elapsed_ticks: 1,
        ..RouteStatus::default()
    }
}

fn counters(started: u32, stops: u32) -> RouteCounters {
    RouteCounters {
        routes_started: started,
        stops_reached: stops,
        ..RouteCounters::default()
    }
}

#[test]
fn a_new_runner_is_disarmed_idle_and_empty() {
    let r = runner();
    let view = r.view(None);
    assert_eq!(
        (view.armed, view.mode, view.current, view.reached),
        (false, RobotMode::Idle, 0, None)
    );
    assert!(r.mission().is_empty());
}

#[test]
fn the_first_start_uses_the_robots_start_and_a_later_one_as_given() {
    let mut r = runner();
    let zero = RouteCounters::default();
    assert_eq!(
        apply(&mut r, Event::LoadRoute, zero),
        (FollowerAction::Keep, Some(Note::MissionLoaded(3)))
    );
    assert_eq!(
        apply(&mut r, Event::Arm, zero),
        (FollowerAction::Keep, Some(Note::Armed))
    );
    assert_eq!(
        apply(&mut r, Event::Start, zero),
        (
            FollowerAction::Run {
                base: 0,
                start: RouteStart::AsGivenHeadingKnown
            },
            Some(Note::Started {
                from: 0,
                resume: false
            })
        )
    );
    assert_eq!(r.mode(), RobotMode::Running);
    assert_eq!(
        apply(&mut r, Event::Pause, zero),
        (FollowerAction::Hold, Some(Note::Paused))
    );
    assert_eq!(r.mode(), RobotMode::Paused);
    // Item 0 was never reached: the continue starts from item 0 again,
    // now as given.
    assert_eq!(
        apply(&mut r, Event::Continue, zero),
        (
            FollowerAction::Run {
                base: 0,
                start: RouteStart::AsGiven
            },
            Some(Note::Started {
                from: 0,
                resume: true
            })
        )
    );
}

#[test]
fn items_are_reached_in_order_and_the_mission_is_done_at_its_end() {
    let mut r = runner();
    let zero = RouteCounters::default();
    for e in [Event::LoadRoute, Event::Arm, Event::Start] {
        apply(&mut r, e, zero);
    }
    // Started and its clock moved: item 0 reached.
    assert!(!r.after_tick(&running(), counters(1, 0), Vec2::new(0.0, 0.0)));
    assert_eq!((r.view(None).reached, r.view(None).current), (Some(0), 1));
    // Far from item 1: not reached.
    assert!(!r.after_tick(&running(), counters(1, 0), Vec2::new(0.5, 0.0)));
    assert_eq!(r.view(None).reached, Some(0));
    // At item 1 (a pass: no settle needed).
    assert!(!r.after_tick(&running(), counters(1, 0), Vec2::new(1.0, 0.0)));
    assert_eq!((r.view(None).reached, r.view(None).current), (Some(1), 2));
    // The route done: the last item reached, the mission done once.
    let done = RouteStatus {
        done: true,
        ..running()
    };
    assert!(r.after_tick(&done, counters(1, 1), Vec2::new(1.0, 1.0)));
    assert_eq!(r.mode(), RobotMode::Done);
    assert_eq!((r.view(None).reached, r.view(None).current), (Some(2), 2));
    assert!(!r.after_tick(&done, counters(1, 1), Vec2::new(1.0, 1.0)));
    // A start after done runs the mission again from item 0.
    assert_eq!(
        apply(&mut r, Event::Start, zero).0,
        FollowerAction::Run {
            base: 0,
            start: RouteStart::AsGiven
        }
    );
    assert_eq!(r.view(None).reached, None);
}

#[test]
fn a_continue_from_a_later_item_starts_where_the_robot_is() {
    let mut r = runner();
    let zero = RouteCounters::default();
    for e in [Event::LoadRoute, Event::Arm, Event::Start] {
        apply(&mut r, e, zero);
    }
    r.after_tick(&running(), counters(1, 0), Vec2::new(0.0, 0.0));
    apply(&mut r, Event::Pause, zero);
    assert_eq!(
        apply(&mut r, Event::Continue, zero),
        (
            FollowerAction::Run {
                base: 0,
                start: RouteStart::FromFirstFix
            },
            Some(Note::Started {
                from: 1,
                resume: true
            })
        )
    );
    // The reached item is kept on a continue.
    assert_eq!((r.view(None).reached, r.view(None).current), (Some(0), 1));
}

#[test]
fn pause_and_continue_only_where_they_apply() {
    let mut r = runner();
    let zero = RouteCounters::default();
    apply(&mut r, Event::LoadRoute, zero);
    assert_eq!(
        apply(&mut r, Event::Pause, zero),
        (FollowerAction::Keep, None)
    );
    assert_eq!(
        apply(&mut r, Event::Continue, zero),
        (FollowerAction::Keep, None)
    );
    assert_eq!(r.mode(), RobotMode::Idle);
}

#[test]
fn failsafes_and_disarm_hold() {
    let zero = RouteCounters::default();
    for (event, mode, note) in [
        (
            Event::EmergencyStop,
            RobotMode::Stopped,
            Note::EmergencyStop,
        ),
        (Event::LinkLost, RobotMode::Stopped, Note::LinkLostStopped),
        (Event::Disarm, RobotMode::Idle, Note::Disarmed),
        (Event::ClearRoute, RobotMode::Idle, Note::Cleared),
    ] {
        let mut r = runner();
        for e in [Event::LoadRoute, Event::Arm, Event::Start] {
            apply(&mut r, e, zero);
        }
        assert_eq!(
            apply(&mut r, event, zero),
            (FollowerAction::Hold, Some(note)),
            "{event:?}"
        );
        assert_eq!(r.mode(), mode, "{event:?}");
        // Holding: ticks no longer move the progress.
        assert!(!r.after_tick(&running(), counters(1, 0), Vec2::new(0.0, 0.0)));
        assert_eq!(r.view(None).reached, None, "{event:?}");
    }
    let mut r = runner();
    assert_eq!(
        apply(&mut r, Event::LinkLost, zero),
        (FollowerAction::Keep, Some(Note::LinkLost))
    );
    assert_eq!(r.mode(), RobotMode::Idle);
}

#[test]
fn a_mission_loaded_while_running_replaces_the_route() {
    let mut r = runner();
    let zero = RouteCounters::default();
    for e in [Event::LoadRoute, Event::Arm, Event::Start] {
        apply(&mut r, e, zero);
    }
    // The replacement's progress counts from the follower's counters now.
    assert_eq!(
        apply(&mut r, Event::LoadRoute, counters(1, 2)),
        (FollowerAction::Replace, Some(Note::MissionReplaces(3)))
    );
    assert_eq!(r.mode(), RobotMode::Running);
    // The old route (started once) is still running: item 0 not reached.
    r.after_tick(&running(), counters(1, 2), Vec2::new(0.0, 0.0));
    assert_eq!(r.view(None).reached, None);
    // The replacement started.
    r.after_tick(&running(), counters(2, 2), Vec2::new(0.0, 0.0));
    assert_eq!(r.view(None).reached, Some(0));
}

#[test]
fn set_current_moves_the_next_start_and_restarts_a_running_route() {
    let mut r = runner();
    let zero = RouteCounters::default();
    apply(&mut r, Event::LoadRoute, zero);
    assert_eq!(
        apply(&mut r, Event::SetCurrent(2), zero),
        (FollowerAction::Keep, None)
    );
    assert_eq!(r.view(None).current, 2);
    assert_eq!(
        apply(&mut r, Event::Start, zero).0,
        FollowerAction::Run {
            base: 1,
            start: RouteStart::FromFirstFix
        }
    );
    assert_eq!(
        apply(&mut r, Event::SetCurrent(1), zero),
        (
            FollowerAction::Run {
                base: 0,
                start: RouteStart::FromFirstFix
            },
            Some(Note::Started {
                from: 1,
                resume: false
            })
        )
    );
}

#[test]
fn load_puts_the_named_route_into_the_follower() {
    let mut r = runner();
    let zero = RouteCounters::default();
    for e in [Event::LoadRoute, Event::Arm] {
        apply(&mut r, e, zero);
    }
    let mut follower = RouteFollower::new(RouteOptions::default());
    r.load(FollowerAction::Keep, &mut follower);
    assert!(!follower.status().pending);
    r.load(FollowerAction::Hold, &mut follower);
    assert!(!follower.status().pending);
    r.load(
        FollowerAction::Run {
            base: 1,
            start: RouteStart::FromFirstFix,
        },
        &mut follower,
    );
    assert!(follower.status().pending);
    let mut follower = RouteFollower::new(RouteOptions::default());
    r.load(FollowerAction::Replace, &mut follower);
    assert!(follower.status().pending);
    // A base past the mission loads nothing.
    let mut follower = RouteFollower::new(RouteOptions::default());
    r.load(
        FollowerAction::Run {
            base: 4,
            start: RouteStart::AsGiven,
        },
        &mut follower,
    );
    assert!(!follower.status().pending);
}
