"""How long an input waited in the node's queue (core/runtime/pairing.py, QueueDelay), from DDS's
source and reception times: the node skips an input that waited too long.
"""

from pma_model_ros.core.runtime.pairing import QueueDelay, SECOND

MS = SECOND // 1000


def test_a_constant_clock_offset_and_transport_time_are_no_wait():
    """The publisher's clock 3 s ahead of the node's, 0.2 ms on the wire: an input taken as it is
    received waited 0; one taken 4 ms after its reception waited 4 ms.
    """
    queue, offset, wire = QueueDelay(), 3 * SECOND, MS // 5
    for t in range(0, 50 * MS, MS):  # 1 kHz, each taken on reception
        assert queue.waited(t + offset, t + wire, t + wire) == 0
    t = 50 * MS
    assert queue.waited(t + offset, t + wire, t + wire + 4 * MS) == 4 * MS


def test_a_slower_input_on_the_wire_waited_its_extra_time():
    """The usual transport time is the lowest seen: an input 1 ms slower on the wire than the
    others (received later) waited 1 ms more, though taken on reception.
    """
    queue = QueueDelay()
    for t in range(0, 10 * MS, MS):
        queue.waited(t, t + MS // 5, t + MS // 5)
    t = 10 * MS
    assert queue.waited(t, t + MS + MS // 5, t + MS + MS // 5) == MS


def test_a_stalled_process_counts_what_was_sent_meanwhile_as_waiting():
    """The node's process stopped for 200 ms (SIGSTOP): what was sent meanwhile is received only
    when it runs again, all at once, and waited from when it was sent; the reception time alone
    would say no input waited.
    """
    queue, wire = QueueDelay(), MS // 5
    for t in range(0, 100 * MS, MS):
        queue.waited(t, t + wire, t + wire)
    resumed = 300 * MS  # sent at 100..299 ms, all received at 300 ms
    waits = [queue.waited(t, resumed, resumed) for t in range(100 * MS, resumed, MS)]
    assert waits[0] == resumed - 100 * MS - wire  # 199.8 ms
    assert waits[-1] == MS - wire
    assert waits == sorted(waits, reverse=True)


def test_a_clock_step_is_followed_within_two_windows():
    """The publisher's clock steps 1 s forward: the lower transport time is taken at once.  It
    steps back again: its inputs look 1 s late (a node skips them) until the lower transport time
    has left both windows, within two seconds.
    """
    queue, t = QueueDelay(), 0
    for _ in range(100):
        queue.waited(t, t, t)
        t += 10 * MS
    step = SECOND
    assert queue.waited(t + step, t, t) == 0  # the lower transport time is taken at once
    t += 10 * MS
    for _ in range(250):  # 2.5 s: both windows hold the stepped clock's inputs only
        waited = queue.waited(t + step, t, t)
        t += 10 * MS
    assert waited == 0
    back = []
    for _ in range(250):  # the clock steps back by 1 s: inputs look 1 s late at first
        back.append(queue.waited(t, t, t))
        t += 10 * MS
    assert back[0] == step and back[-1] == 0
