"""The gRPC stubs of activefoam.v1, generated from proto/ (scripts/python-stubs.sh)."""
