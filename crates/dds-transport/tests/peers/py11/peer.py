"""Cyclone DDS 11 (Python binding, typed topics with XTypes type information) test peer.

Modes (all on loopback, bounded in time, output on stdout as JSON lines):
  pub-lowcmd   --domain D [--count N] [--rate HZ]       typed hg LowCmd_ on rt/lowcmd
  pub-lowstate --domain D [--count N] [--rate HZ] [--gap-at I]
                                                        typed hg LowState_ on rt/lowstate, tick += 2
  echo         --domain D [--seconds S]                 rt/lowcmd in, rt/lowstate out (q echoed)
  sub          --domain D --topic T [--count N] [--seconds S]   prints each sample received
  discover     --domain D [--seconds S]                 endpoints seen in discovery, with QoS and
                                                        whether they carry XTypes type information
Discovery: --sdk uses unitree_sdk2py's ChannelFactoryInitialize(D, "lo") (Unitree's own config);
otherwise the same unicast settings as our transport (participant index auto, peer 127.0.0.1).
Misconfigurations for `ulab doctor`'s tests: --go (unitree_go types on the topic: the wrong family for an
H1-2), --writer-qos best-effort, --reader-qos reliable|transient-local (QoS that cannot match Unitree's).
"""
import argparse
import json
import sys
import time
import types

# The unitree_sdk2py wheel imports a `b2` subpackage it does not ship.
sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))

from cyclonedds.core import Qos, Policy  # noqa: E402
from cyclonedds.domain import Domain, DomainParticipant  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402
from unitree_sdk2py.idl.default import unitree_hg_msg_dds__LowCmd_, unitree_hg_msg_dds__LowState_  # noqa: E402
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowCmd_, LowState_  # noqa: E402
from unitree_sdk2py.idl.unitree_go.msg.dds_ import LowCmd_ as GoLowCmd_, LowState_ as GoLowState_  # noqa: E402

TYPES = {"rt/lowcmd": LowCmd_, "rt/lowstate": LowState_}
GO_TYPES = {"rt/lowcmd": GoLowCmd_, "rt/lowstate": GoLowState_}
WRITER_QOS = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(1))
READER_QOS = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(64))
QOS_CHOICES = {
    "best-effort": Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(1)),
    "reliable": Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(64)),
    "transient-local": Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(64), Policy.Durability.TransientLocal),
}


def writer_qos(args):
    return QOS_CHOICES[args.writer_qos] if args.writer_qos else WRITER_QOS


def reader_qos(args):
    return QOS_CHOICES[args.reader_qos] if args.reader_qos else READER_QOS


def topic_type(args, name):
    return (GO_TYPES if args.go else TYPES)[name]

XML = (
    '<CycloneDDS><Domain Id="any"><General><Interfaces><NetworkInterface name="lo" priority="default" '
    'multicast="default"/></Interfaces></General><Discovery><ParticipantIndex>auto</ParticipantIndex>'
    "<MaxAutoParticipantIndex>32</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers>"
    "</Discovery></Domain></CycloneDDS>"
)


_KEEP = []


def emit(obj):
    print(json.dumps(obj), flush=True)


def participant(args):
    if args.sdk:
        from unitree_sdk2py.core.channel import ChannelFactoryInitialize

        ChannelFactoryInitialize(args.domain, "lo")
        return DomainParticipant(args.domain)
    # Keep the Domain object alive: once collected, its configuration is gone and a participant
    # would silently get Cyclone's defaults instead.
    _KEEP.append(Domain(args.domain, XML))
    return DomainParticipant(args.domain)


def wait_matched(entity, seconds):
    end = time.time() + seconds
    while time.time() < end:
        try:
            m = entity.get_matched_subscriptions() if isinstance(entity, DataWriter) else entity.get_matched_publications()
        except Exception:
            m = []
        if m:
            return True
        time.sleep(0.02)
    return False


def cmd_pattern(i):
    c = unitree_hg_msg_dds__LowCmd_()
    c.mode_machine = 6
    for k in range(35):
        c.motor_cmd[k].mode = 1
        c.motor_cmd[k].q = 0.5 + 0.01 * k
    c.motor_cmd[0].kp = float(i)
    c.crc = 1000 + i
    return c


def pub(args, topic_name):
    dp = participant(args)
    w = DataWriter(dp, Topic(dp, topic_name, topic_type(args, topic_name)), qos=writer_qos(args))
    emit({"event": "ready", "matched": wait_matched(w, args.match_timeout)})
    period = 1.0 / args.rate
    t0 = time.time()
    tick_extra = 0
    for i in range(args.count):
        if i == args.gap_at:
            # Simulated outage: 0.3 s of silence and 15 samples' worth of ticks lost.
            time.sleep(0.3)
            t0 += 0.3
            tick_extra += 30
        if topic_name == "rt/lowcmd":
            w.write(cmd_pattern(i))
        else:
            s = unitree_hg_msg_dds__LowState_()
            s.tick = 2 * i + 2 + tick_extra
            s.mode_machine = 6
            s.motor_state[0].q = 0.001 * i
            s.crc = 5000 + i
            w.write(s)
        nxt = t0 + (i + 1) * period
        time.sleep(max(0.0, nxt - time.time()))
    time.sleep(0.3)
    emit({"event": "done", "sent": args.count})


def echo(args):
    dp = participant(args)
    r = DataReader(dp, Topic(dp, "rt/lowcmd", LowCmd_), qos=READER_QOS)
    w = DataWriter(dp, Topic(dp, "rt/lowstate", LowState_), qos=WRITER_QOS)
    emit({"event": "ready"})
    state = unitree_hg_msg_dds__LowState_()
    state.mode_machine = 6
    n = 0
    end = time.time() + args.seconds
    while time.time() < end:
        for c in r.take(N=64):
            if not hasattr(c, "motor_cmd"):
                continue
            n += 1
            for k in range(35):
                state.motor_state[k].q = c.motor_cmd[k].q
            state.reserve[0] = n
            state.reserve[1] = c.crc
            emit({"event": "cmd", "n": n, "q0": c.motor_cmd[0].q, "q34": c.motor_cmd[34].q, "kp0": c.motor_cmd[0].kp, "crc": c.crc})
        state.tick += 10
        w.write(state)
        time.sleep(0.01)
    emit({"event": "done", "received": n})


def sub(args):
    dp = participant(args)
    r = DataReader(dp, Topic(dp, args.topic, topic_type(args, args.topic)), qos=reader_qos(args))
    emit({"event": "ready"})
    n = 0
    end = time.time() + args.seconds
    while time.time() < end and n < args.count:
        got = False
        for s in r.take(N=64):
            if not hasattr(s, "crc"):
                continue
            got = True
            n += 1
            rec = {"event": "sample", "t": time.time(), "crc": s.crc}
            if args.topic == "rt/lowstate":
                rec["tick"] = s.tick
                rec["q0"] = s.motor_state[0].q
            else:
                rec["q0"] = s.motor_cmd[0].q
                rec["kp0"] = s.motor_cmd[0].kp
            emit(rec)
        if not got:
            time.sleep(0.002)
    emit({"event": "done", "received": n})


def qos_text(qos):
    out = {}
    for name, policy in (("reliability", Policy.Reliability), ("history", Policy.History), ("durability", Policy.Durability)):
        try:
            out[name] = str(qos[policy])
        except Exception:  # noqa: BLE001 (policy absent: Cyclone default)
            out[name] = None
    return out


def discover(args):
    """Lists the endpoints seen through the builtin topics, ours (a typed control writer) included."""
    from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription

    dp = participant(args)
    control = DataWriter(dp, Topic(dp, "rt/lowcmd", LowCmd_), qos=WRITER_QOS)  # noqa: F841
    readers = [("publication", BuiltinDataReader(dp, BuiltinTopicDcpsPublication)),
               ("subscription", BuiltinDataReader(dp, BuiltinTopicDcpsSubscription))]
    emit({"event": "ready"})
    seen = set()
    end = time.time() + args.seconds
    while time.time() < end:
        for kind, r in readers:
            for e in r.take(N=64):
                if not hasattr(e, "topic_name") or e.key in seen:
                    continue
                seen.add(e.key)
                emit({"event": "endpoint", "kind": kind, "topic": e.topic_name, "type": e.type_name,
                      "local": e.participant_key == dp.guid, "has_type_info": e.type_id is not None,
                      "qos": qos_text(e.qos)})
        time.sleep(0.02)
    emit({"event": "done", "endpoints": len(seen)})


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["pub-lowcmd", "pub-lowstate", "echo", "sub", "discover"])
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--count", type=int, default=100)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--topic", default="rt/lowstate")
    ap.add_argument("--match-timeout", type=float, default=5.0)
    ap.add_argument("--sdk", action="store_true")
    ap.add_argument("--gap-at", type=int, default=-1, help="pub-lowstate: pause and skip ticks at this sample")
    ap.add_argument("--go", action="store_true", help="pub/sub: unitree_go types instead of unitree_hg")
    ap.add_argument("--writer-qos", choices=sorted(QOS_CHOICES), help="pub: writer QoS instead of Unitree's")
    ap.add_argument("--reader-qos", choices=sorted(QOS_CHOICES), help="sub: reader QoS instead of Unitree's")
    args = ap.parse_args()
    if args.domain == 0:
        sys.exit("refusing domain 0")
    if args.go and args.mode != "sub":
        sys.exit("--go is for sub only (the samples written are hg)")
    if args.mode == "pub-lowcmd":
        pub(args, "rt/lowcmd")
    elif args.mode == "pub-lowstate":
        pub(args, "rt/lowstate")
    elif args.mode == "echo":
        echo(args)
    elif args.mode == "discover":
        discover(args)
    else:
        sub(args)


if __name__ == "__main__":
    main()
