"""Program -> Job: offsets, ordering, nm -> steps, soft limits (`plan_file` is the
one pipeline every front end calls).
"""
