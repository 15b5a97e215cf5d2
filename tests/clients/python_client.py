#!/usr/bin/env python3
"""A Strider client built from proto/ alone with a standard gRPC toolchain (grpcio and
grpc-tools): the integration test generates the stubs into STUBS_DIR with
`python3 -m grpc_tools.protoc -I proto --python_out DIR --grpc_python_out DIR
strider/v1/strider.proto`, then runs this script.

Usage: python_client.py STUBS_DIR URL SECRET
Prints one JSON object: the progress, the first page of elites, the same elites read
two at a time with page tokens, one elite whole, what a call without the secret got, and
what a forged page token and a token reused with another page size got.
"""

import json
import sys

sys.path.insert(0, sys.argv[1])
import grpc  # noqa: E402
from google.protobuf import wrappers_pb2  # noqa: E402
from strider.v1 import strider_pb2 as pb  # noqa: E402
from strider.v1 import strider_pb2_grpc as rpc  # noqa: E402

target = sys.argv[2].replace("http://", "")
secret = sys.argv[3]
auth = (("authorization", "Bearer " + secret),)
channel = grpc.insecure_channel(target)
client = rpc.ClientServiceStub(channel)

progress = client.GetProgress(pb.ProgressRequest(protocol_version=1), metadata=auth)
page = client.ListElites(
    pb.ListElitesRequest(
        protocol_version=1, run=wrappers_pb2.UInt32Value(value=0), page_size=1000
    ),
    metadata=auth,
)
paged = []
token = ""
while True:
    p = client.ListElites(
        pb.ListElitesRequest(
            protocol_version=1,
            run=wrappers_pb2.UInt32Value(value=0),
            page_size=2,
            page_token=token,
        ),
        metadata=auth,
    )
    paged.extend(p.elites)
    if not p.next_page_token:
        break
    token = p.next_page_token
    issued = token


def refusal(request):
    try:
        client.ListElites(request, metadata=auth)
        return "OK"
    except grpc.RpcError as e:
        return e.code().name


forged = refusal(
    pb.ListElitesRequest(protocol_version=1, page_token="18446744073709551615")
)
reused = refusal(
    pb.ListElitesRequest(
        protocol_version=1,
        run=wrappers_pb2.UInt32Value(value=0),
        page_size=3,
        page_token=issued,
    )
)
best = page.elites[0]
elite = client.GetElite(
    pb.GetEliteRequest(protocol_version=1, run=best.run, cell=best.cell), metadata=auth
)
try:
    client.GetProgress(pb.ProgressRequest(protocol_version=1))
    without_secret = "OK"
except grpc.RpcError as e:
    without_secret = e.code().name

print(
    json.dumps(
        {
            "experiment": progress.experiment,
            "runs": [
                {"run": r.run, "generation": r.generation, "finished": r.finished,
                 "best_fitness": r.best_fitness}
                for r in progress.runs
            ],
            "elites": [
                {"run": e.run, "cell": e.cell, "candidate": e.candidate, "fitness": e.fitness}
                for e in page.elites
            ],
            "elite": {
                "fitness": elite.summary.fitness,
                "morphology": len(elite.genome.morphology),
                "controller": len(elite.genome.controller),
                "kind": elite.outcome.WhichOneof("kind"),
            },
            "paged": [
                {"run": e.run, "cell": e.cell, "candidate": e.candidate, "fitness": e.fitness}
                for e in paged
            ],
            "forged_token": forged,
            "reused_token": reused,
            "without_secret": without_secret,
        }
    )
)
