"""Accounts, logins, device credentials and the experimenters' assistance limits (issue #13)."""

from gaitscope.sessions.accounts.accounts import REFUSED, Accounts, Login, LoginFailed
from gaitscope.sessions.accounts.throttle import LoginThrottle
from gaitscope.sessions.accounts.watch import LoginWatch

__all__ = ["REFUSED", "Accounts", "Login", "LoginFailed", "LoginThrottle", "LoginWatch"]
