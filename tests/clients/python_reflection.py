"""Asks a coordinator what it serves through gRPC server reflection, as grpcio-reflection's
client does (v1alpha, the version Python's tools speak), and fetches the file that defines
the worker service. Prints JSON: the services listed, and the services and messages in the
returned file descriptor.

Usage: python3 python_reflection.py HOST:PORT SECRET
"""
import json
import sys

import grpc
from google.protobuf import descriptor_pb2
from grpc_reflection.v1alpha import reflection_pb2, reflection_pb2_grpc

target, secret = sys.argv[1], sys.argv[2]
metadata = [("authorization", f"Bearer {secret}")]
stub = reflection_pb2_grpc.ServerReflectionStub(grpc.insecure_channel(target))


def ask(request):
    answers = stub.ServerReflectionInfo(iter([request]), metadata=metadata, timeout=30)
    return next(iter(answers))


listed = ask(reflection_pb2.ServerReflectionRequest(list_services=""))
services = sorted(s.name for s in listed.list_services_response.service)

found = ask(reflection_pb2.ServerReflectionRequest(
    file_containing_symbol="strider.v1.WorkerService"))
files = [descriptor_pb2.FileDescriptorProto.FromString(raw)
         for raw in found.file_descriptor_response.file_descriptor_proto]
print(json.dumps({
    "services": services,
    "file": [f.name for f in files],
    "file_services": sorted(s.name for f in files for s in f.service),
    "file_messages": sorted(m.name for f in files for m in f.message_type),
}))
