//! The request list's tests: the paper's order within a display, the fair
//! share between displays, and the bounds on its heaps.

use super::*;

fn k(b: u32) -> BeamKey {
    BeamKey::new(0, b)
}

#[test]
fn the_neediest_beam_comes_first_and_nothing_is_handed_out_twice() {
    let mut list = RequestList::new();
    list.request(1, &[(k(1), 100, 50), (k(2), 100, 0), (k(3), 10, 10)], None, true);
    let p = list.next(10, 10);
    assert_eq!(p.len(), 1);
    assert_eq!((p[0].key, p[0].rays), (k(2), 10));
    // Beam 2 is at 10%, beam 1 at 50%: beam 2 keeps coming until it catches up.
    let p = list.next(40, 10);
    assert!(p.iter().all(|x| x.key == k(2)), "{p:?}");
    let p = list.next(1000, 1000);
    let total: u64 = p.iter().map(|x| u64::from(x.rays)).sum();
    assert_eq!(total, 50 + 50, "exactly what is missing, once");
    assert!(list.next(1000, 10).is_empty());
    assert_eq!(list.missing(), 0);
}

#[test]
fn merged_requests_want_the_most_any_display_wants_and_leave_with_their_display() {
    let mut list = RequestList::new();
    list.request(1, &[(k(1), 10, 0)], None, true);
    list.request(2, &[(k(1), 30, 0), (k(2), 5, 0)], None, true);
    assert_eq!(list.missing(), 35);
    assert_eq!(list.finished(k(1), 4, false), vec![1, 2]);
    list.drop_display(2);
    assert_eq!(list.missing(), 6, "beam 1 back to display 1's 10, beam 2 gone");
    assert_eq!(list.len(), 1);
    list.drop_display(1);
    assert!(list.is_empty());
    assert!(list.next(100, 10).is_empty());
}

#[test]
fn a_new_view_replaces_the_old_requests_and_lost_packets_are_rescheduled() {
    let mut list = RequestList::new();
    let eye = EyePoint {
        position: [1.0, 2.0, 3.0],
        radius: 0.1,
        frustum: None,
    };
    list.request(1, &[(k(1), 10, 0), (k(2), 10, 0)], Some(eye), true);
    let out = list.next(20, 10);
    assert_eq!(out.len(), 2);
    assert!(out.iter().all(|p| p.eye == Some(eye)));
    list.give_back(k(1), 10);
    assert_eq!(list.missing(), 10);
    list.request(1, &[(k(3), 4, 0)], None, true);
    // Beam 2 still has rays in flight; when they land nobody wants them.
    assert!(list.finished(k(2), 10, true).is_empty());
    assert_eq!(list.missing(), 4);
    let out = list.next(100, 10);
    assert_eq!(
        out,
        vec![RequestPacket {
            key: k(3),
            rays: 4,
            eye: None
        }]
    );
    // Adding (not replacing) keeps the earlier request.
    list.request(1, &[(k(4), 2, 0)], None, false);
    assert_eq!(list.len(), 2);
}

/// Hands out `budget`-ray calls of packets of at most 16 rays, each
/// packet traced at once, until `modest`'s beams hold `asked` rays;
/// returns the rays that went to its beams and to everyone else's.
fn serve_until_met(list: &mut RequestList, modest: &[BeamKey], asked: u64, budget: u64) -> (u64, u64) {
    let (mut mine, mut others) = (0u64, 0u64);
    for _ in 0..10_000 {
        if mine >= asked {
            break;
        }
        for p in list.next(budget, 16) {
            list.finished(p.key, p.rays, true);
            if modest.contains(&p.key) {
                mine += u64::from(p.rays);
            } else {
                others += u64::from(p.rays);
            }
        }
    }
    (mine, others)
}

/// A greedy display served alone for 20 budgets of 256 rays, then a
/// modest one asks: returns the rays that went to the modest display's
/// beams and to the greedy one's until the modest request was met.
fn greedy_then_modest(list: &mut RequestList) -> (u64, u64) {
    // The greedy display: 1,000 beams of 100 rays, asked for first and
    // served alone for a while.
    let greedy: Vec<(BeamKey, u32, u64)> = (1000..2000).map(|b| (k(b), 100, 0)).collect();
    list.request(2, &greedy, None, true);
    let mut alone = 0;
    for _ in 0..20 {
        for p in list.next(256, 16) {
            list.finished(p.key, p.rays, true);
            alone += u64::from(p.rays);
        }
    }
    assert_eq!(alone, 20 * 256, "alone, it takes every budget");
    // The modest one: 20 beams of 50 rays (a 50th of the beams, a 100th of the rays).
    let modest: Vec<BeamKey> = (0..20).map(k).collect();
    let asked = 20 * 50;
    list.request(1, &modest.iter().map(|&b| (b, 50, 0)).collect::<Vec<_>>(), None, true);
    let (mine, others) = serve_until_met(list, &modest, asked, 256);
    assert_eq!(mine, asked, "exactly what it asked for");
    // Met, it takes nothing: the greedy display gets every ray again.
    let rest = list.next(256, 16);
    assert!(rest.iter().all(|p| !modest.contains(&p.key)), "{rest:?}");
    assert_eq!(rest.iter().map(|p| u64::from(p.rays)).sum::<u64>(), 256);
    (mine, others)
}

#[test]
fn a_greedy_display_does_not_starve_a_modest_one() {
    let mut list = RequestList::new();
    let (mine, others) = greedy_then_modest(&mut list);
    let (asked, total) = (mine, mine + others);
    assert!(
        mine as f64 >= 0.45 * total as f64,
        "the modest display got {mine} of {total} rays while both waited"
    );
    assert!(
        others as f64 >= 0.45 * total as f64,
        "an idle spell earns no credit: the greedy display still got {others} of {total}"
    );
    assert!(
        total <= 2 * asked + 256,
        "met after {total} rays, about twice what it asked for"
    );
}

#[test]
fn the_merged_order_lets_the_greedy_display_take_nearly_everything() {
    let mut list = RequestList::with_share(Share::Merged);
    let (mine, others) = greedy_then_modest(&mut list);
    // Its beams reach 50 rays only once the greedy display's 1,000 beams
    // are nearly as full: it gets about a hundredth of the rays.
    assert!(others > 50 * mine, "{mine} vs {others}");
    // Switching to a fair share reorders what is left.
    list.request(3, &[(k(5000), 64, 0)], None, true);
    list.set_share(Share::Fair);
    let p = list.next(64, 16);
    assert_eq!(p.iter().filter(|p| p.key == k(5000)).count(), 2, "{p:?}");
}

#[test]
fn a_beam_two_displays_want_counts_for_both() {
    let mut list = RequestList::new();
    // Display 1 wants 10 beams; display 2 the same beams and 10 more.
    let shared: Vec<(BeamKey, u32, u64)> = (0..10).map(|b| (k(b), 100, 0)).collect();
    let own: Vec<(BeamKey, u32, u64)> = (10..20).map(|b| (k(b), 100, 0)).collect();
    list.request(1, &shared, None, true);
    list.request(2, &[shared.clone(), own].concat(), None, true);
    let (mut one, mut two) = (0u64, 0u64);
    while one < 1000 {
        for p in list.next(16, 16) {
            list.finished(p.key, p.rays, true);
            if p.key.beam < 10 {
                one += u64::from(p.rays);
            }
            two += u64::from(p.rays);
        }
        // Both receive the shared beams' rays: neither is owed turns.
        assert!(one.abs_diff(two) <= 16, "display 1 got {one}, display 2 {two}");
    }
    // Display 1 is met: display 2's own beams get every ray.
    let p = list.next(160, 16);
    assert!(p.iter().all(|p| p.key.beam >= 10), "{p:?}");
    assert_eq!(list.missing(), 1000 - (two - one) - 160);
}

#[test]
fn many_changes_keep_the_heap_bounded() {
    let mut list = RequestList::new();
    for i in 0..20_000u32 {
        list.request(1, &[(k(i % 7), 1000, 0)], None, false);
    }
    assert!(list.displays[&1].queue.len() <= queue_bound(7));
}
