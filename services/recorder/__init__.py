"""Recording and replay: any set of topics to MCAP with protobuf schemas, and back onto Zenoh.
"""
