"""rctp/msg: the message grammar of RCTP/2.0 and what a server does with bad messages.

- `messages`: the basic messages and bad start lines and fields.
- `grammar`: line endings, fields, framing, limits, targets, and the order of answers.
- `answers`: the server's own requests and the answers it takes to them.
"""
