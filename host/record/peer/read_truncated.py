"""Reads an MCAP file that may have been cut short (a crash, `kill -9`) the way the MCAP
library itself does: Foxglove's StreamReader, record by record, until the file ends. Each
message is decoded with rosbags' CDR decoder, its type parsed from the file's own schema.
Prints one JSON line: messages read, the newest log time (ns), topics, how the file ended.

usage: read_truncated.py FILE.mcap
"""

import json
import sys
from collections import Counter

from mcap.exceptions import EndOfFile, RecordLengthLimitExceeded
from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.msg import get_types_from_msg


def main():
    store = get_typestore(Stores.EMPTY)
    schemas, channels, topics = {}, {}, Counter()
    last, ended = 0, "truncated"
    with open(sys.argv[1], "rb") as f:
        try:
            for record in StreamReader(f, validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                    types = get_types_from_msg(record.data.decode(), record.name)
                    store.register({k: v for k, v in types.items() if k not in store.fielddefs})
                elif isinstance(record, Channel):
                    channels[record.id] = (record.topic, schemas[record.schema_id])
                elif isinstance(record, Message):
                    topic, msgtype = channels[record.channel_id]
                    store.deserialize_cdr(record.data, msgtype)
                    topics[topic] += 1
                    last = max(last, record.log_time)
                elif isinstance(record, Footer):
                    ended = "footer"
        except EndOfFile:
            pass
        except RecordLengthLimitExceeded as e:
            # A chunk's length is written when the chunk is closed: the one being written at
            # the cut still has the writer's placeholder, all ones.
            if f"length {2**64 - 1} " not in str(e):
                raise
            ended = "in an unfinished chunk"
    print(json.dumps({"messages": sum(topics.values()), "last_ns": last,
                      "topics": dict(topics), "ended": ended}))


if __name__ == "__main__":
    main()
