"""Accounts, logins, device credentials and the experimenters' assistance limits (issue #13)."""

from sessions.accounts.accounts import Accounts, Login, LoginFailed

__all__ = ["Accounts", "Login", "LoginFailed"]
