"""Sending a Job: the streamer (character counting, resend), the journal, resume.
"""
