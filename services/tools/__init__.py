"""Small commands around the stack: topics, echo, router."""
